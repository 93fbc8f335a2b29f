//! Sequence trackers on rendered TUM sequences with exact ground truth.

use std::io;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::OnceLock;

use nalgebra::Isometry3;

use vofront::dataset::{Dataset, DatasetError, Frame};
use vofront::eval::{ate, Alignment, EvalConfig};
use vofront::fixtures::scene::{default_camera, rescaled_camera, room_trajectory, Scene};
use vofront::fixtures::tum::write_tum_sequence;
use vofront::odometry::direct::{DirectTracker, DirectTrackerConfig};
use vofront::odometry::feature_rgbd::{FeatureRgbdConfig, FeatureRgbdTracker};
use vofront::odometry::mono::{MonoConfig, MonoTracker};
use vofront::odometry::observe::Observed;
use vofront::odometry::run::{
    run, run_observed, run_with, FrameRecord, RunControl, RunError, RunSummary,
};
use vofront::odometry::{FrameEstimate, FrameQuality, TrackStatus, Tracker};
use vofront::trajectory::Trajectory;

/// Frames in the synthetic sequences (about 1 cm and 0.3 deg per frame).
const FRAMES: usize = 40;
/// ATE bound of the direct tracker on noiseless renders, metres: frame-to-keyframe errors are
/// a fraction of a millimetre, so 40 frames of drift stay well below it.
const DIRECT_ATE_M: f64 = 0.005;
/// ATE bound of the ORB + PnP tracker, metres: pixel-level keypoint noise at 2-6 m depth.
const FEATURE_RGBD_ATE_M: f64 = 0.01;
/// Monocular ATE bound after Sim(3) alignment, metres.
const MONO_ATE_M: f64 = 0.02;
/// Frames the monocular tracker may need before the parallax allows initialisation
/// (about 0.15 deg of parallax per frame in the room sequence, 1 deg needed).
const MONO_MAX_INIT_FRAMES: usize = 15;

fn sequence(name: &str, width: u32, height: u32) -> (PathBuf, Dataset) {
    let dir = std::env::temp_dir().join(format!("vofront-odometry-{name}-{}", std::process::id()));
    let camera = scaled_camera(width);
    write_tum_sequence(
        &dir,
        &Scene::box_room(5),
        &camera,
        (width, height),
        &room_trajectory(FRAMES),
    )
    .unwrap();
    let dataset = Dataset::open(&dir).unwrap();
    (dir, dataset)
}

/// The default camera for an image `width` pixels wide (same field of view).
fn scaled_camera(width: u32) -> vofront::geometry::Camera {
    rescaled_camera(&default_camera(), width as f64 / 640.0)
}

/// The 640x480 room sequence, rendered once and shared by the tests that only read it.
fn shared_sequence() -> &'static Dataset {
    static SEQUENCE: OnceLock<Dataset> = OnceLock::new();
    SEQUENCE.get_or_init(|| sequence("shared", 640, 480).1)
}

/// ATE RMSE (metres) of `est` against `gt` after `alignment`.
fn ate_rmse(gt: &Trajectory, est: &Trajectory, alignment: Alignment) -> f64 {
    let cfg = EvalConfig {
        alignment,
        ..EvalConfig::default()
    };
    ate(gt, est, &cfg).unwrap().stats.rmse
}

fn direct_tracker(width: u32) -> DirectTracker {
    DirectTracker::new(scaled_camera(width), DirectTrackerConfig::default())
}

#[test]
fn direct_tracker_follows_the_room_sequence() {
    let dataset = shared_sequence();
    let mut tracker = direct_tracker(640);
    let out = run(dataset, &mut tracker, None, |_, _| {});
    assert_eq!(out.summary.lost + out.summary.reinitialised, 0);
    assert_eq!(out.trajectory.len(), FRAMES);
    assert!(
        out.summary.keyframes >= 2,
        "the camera moves far enough to need new keyframes"
    );
    let first = out.trajectory.poses[0].1;
    assert!(
        first.translation.vector.norm() < 1e-12,
        "first frame at the origin"
    );
    let gt = dataset.ground_truth.clone().unwrap();
    let a = ate_rmse(&gt, &out.trajectory, Alignment::Se3);
    assert!(a < DIRECT_ATE_M, "ATE {} m", a);
}

#[test]
fn a_textureless_stretch_is_lost_and_tracking_recovers() {
    let (dir, dataset) = sequence("flat", 320, 240);
    // Frames 15..20 become a flat grey wall: nothing to align.
    for i in 15..20 {
        let path = &dataset.frames[i].image;
        image::RgbImage::from_pixel(320, 240, image::Rgb([120, 120, 120]))
            .save(path)
            .unwrap();
    }
    let mut tracker = direct_tracker(320);
    let out = run(&dataset, &mut tracker, None, |_, _| {});
    let status: Vec<TrackStatus> = out
        .records
        .iter()
        .map(|r| r.estimate.as_ref().unwrap().status)
        .collect();
    assert!(
        status[15..20].iter().all(|s| *s == TrackStatus::Lost),
        "{status:?}"
    );
    assert_eq!(status[20], TrackStatus::Reinitialised, "{status:?}");
    assert!(
        status[21..].iter().all(|s| *s == TrackStatus::Ok),
        "{status:?}"
    );
    assert!(!RunSummary::lost_for_good(&out.records));
    assert_eq!(out.trajectory.len(), FRAMES - 5);
    std::fs::remove_dir_all(dir).ok();
}

#[test]
fn frames_without_depth_are_lost_not_fatal() {
    let (dir, dataset) = sequence("nodepth", 160, 120);
    let mut tracker = direct_tracker(160);
    let frame = dataset.load(0).unwrap().without_depth();
    let e = tracker.track(&frame);
    assert_eq!(e.status, TrackStatus::Lost);
    assert!(e.message.unwrap().contains("depth"));
    std::fs::remove_dir_all(dir).ok();
}

#[test]
fn an_unreadable_frame_is_a_typed_error_and_the_run_goes_on() {
    let (dir, _) = sequence("corrupt", 160, 120);
    let mut images: Vec<PathBuf> = std::fs::read_dir(dir.join("rgb"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    images.sort();
    std::fs::write(&images[3], b"not a png").unwrap();
    let dataset = Dataset::open(&dir).unwrap();
    let out = run(&dataset, &mut direct_tracker(160), Some(8), |_, _| {});
    assert_eq!(out.records.len(), 8);
    assert_eq!(out.summary.unreadable, 1);
    let why = out.records[3].estimate.as_ref().unwrap_err();
    assert!(
        matches!(**why, DatasetError::Image { index: 3, ref path, .. } if *path == images[3]),
        "{why}"
    );
    assert!(out.records[4..].iter().all(|r| r
        .estimate
        .as_ref()
        .is_ok_and(|e| e.status != TrackStatus::Lost)));
    std::fs::remove_dir_all(dir).ok();
}

#[test]
fn feature_rgbd_tracker_follows_the_room_sequence() {
    let dataset = shared_sequence();
    let mut tracker =
        FeatureRgbdTracker::new(scaled_camera(640), FeatureRgbdConfig::default()).unwrap();
    let out = run(dataset, &mut tracker, None, |_, _| {});
    assert_eq!(out.summary.lost + out.summary.reinitialised, 0);
    let gt = dataset.ground_truth.clone().unwrap();
    let a = ate_rmse(&gt, &out.trajectory, Alignment::Se3);
    assert!(a < FEATURE_RGBD_ATE_M, "ATE {} m", a);
    let scored = out
        .records
        .iter()
        .filter_map(|r| r.estimate.as_ref().ok())
        .skip(1);
    assert!(scored
        .clone()
        .all(|e| e.quality.inliers >= 25 && e.quality.covariance_trace.is_some_and(|t| t > 0.0)));
}

#[test]
fn monocular_tracker_initialises_and_keeps_a_consistent_scale() {
    let dataset = shared_sequence();
    let mut tracker = MonoTracker::new(scaled_camera(640), MonoConfig::default()).unwrap();
    let out = run(dataset, &mut tracker, None, |_, _| {});
    let status: Vec<TrackStatus> = out
        .records
        .iter()
        .map(|r| r.estimate.as_ref().unwrap().status)
        .collect();
    // The frames the initialisation waited through are located in its map once it exists
    // (`Tracker::revised`), so every frame is tracked.
    assert!(status.iter().all(|s| *s == TrackStatus::Ok), "{status:?}");
    let waited = out
        .records
        .iter()
        .filter(|r| {
            let message = r.estimate.as_ref().unwrap().message.as_deref();
            message.is_some_and(|m| m.contains("waited for parallax"))
        })
        .count();
    assert!((1..MONO_MAX_INIT_FRAMES).contains(&waited), "{waited}");
    assert_eq!(out.trajectory.len(), FRAMES);
    let gt = dataset.ground_truth.clone().unwrap();
    let a = ate_rmse(&gt, &out.trajectory, Alignment::Sim3);
    assert!(a < MONO_ATE_M, "ATE {} m", a);
    // A rigid alignment cannot fix the arbitrary scale: the trajectory is not metric.
    let rigid = ate_rmse(&gt, &out.trajectory, Alignment::Se3);
    assert!(rigid > 5.0 * a);
}

/// A scripted tracker: frames 1-3 are reported lost while it "waits" (1 ms each), pending, and
/// replaced at frame 4 by estimates at `x = index` (0.25 ms of late work each); it raises
/// `stop` after tracking frame `stop_after`.
struct LateTracker<'a> {
    frames: usize,
    revised: Vec<(usize, FrameEstimate)>,
    stop: &'a AtomicBool,
    stop_after: usize,
}

impl LateTracker<'_> {
    const WAITED: std::ops::Range<usize> = 1..4;

    fn estimate(index: usize, status: TrackStatus, ms: f64) -> FrameEstimate {
        FrameEstimate {
            pose_wc: Isometry3::translation(index as f64, 0.0, 0.0),
            status,
            quality: FrameQuality {
                ms,
                ..FrameQuality::default()
            },
            message: None,
            pose_quality: None,
        }
    }
}

impl Tracker for LateTracker<'_> {
    fn track(&mut self, _: &Frame) -> FrameEstimate {
        let index = self.frames;
        self.frames += 1;
        self.stop.store(index == self.stop_after, Ordering::SeqCst);
        if index == Self::WAITED.end {
            let late = Self::WAITED.map(|k| (index - k, Self::estimate(k, TrackStatus::Ok, 0.25)));
            self.revised = late.collect();
        }
        if Self::WAITED.contains(&index) {
            Self::estimate(0, TrackStatus::Lost, 1.0)
        } else {
            Self::estimate(index, TrackStatus::Ok, 1.0)
        }
    }

    fn pending(&self) -> usize {
        let last = self.frames - 1;
        if Self::WAITED.contains(&last) {
            last
        } else {
            0
        }
    }

    fn revised(&mut self) -> Vec<(usize, FrameEstimate)> {
        std::mem::take(&mut self.revised)
    }
}

/// Runs a [`LateTracker`] over the first `frames` frames of the room sequence, stopping after
/// frame `stop_after`; the sink's (index, status, x) in the order it saw them, and the output.
fn run_late(
    frames: usize,
    stop_after: usize,
) -> (
    Vec<(usize, TrackStatus, f64)>,
    vofront::odometry::run::RunOutput,
) {
    let stop = AtomicBool::new(false);
    let mut tracker = LateTracker {
        frames: 0,
        revised: Vec::new(),
        stop: &stop,
        stop_after,
    };
    let mut seen = Vec::new();
    let mut sink = |r: &FrameRecord| {
        let e = r.estimate.as_ref().unwrap();
        seen.push((r.index, e.status, e.pose_wc.translation.x));
        Ok(())
    };
    let control = RunControl {
        max_frames: Some(frames),
        stop: Some(&stop),
    };
    let out = run_with(shared_sequence(), &mut tracker, &control, &mut sink).unwrap();
    (seen, out)
}

#[test]
fn revised_frames_reach_the_sink_in_order_with_their_late_estimates() {
    let (seen, out) = run_late(6, usize::MAX);
    let expected: Vec<(usize, TrackStatus, f64)> =
        (0..6).map(|i| (i, TrackStatus::Ok, i as f64)).collect();
    assert_eq!(seen, expected);
    assert_eq!((out.summary.frames, out.summary.lost), (6, 0));
    assert_eq!(out.trajectory.len(), 6);
    // A revised frame's time is its first answer's and the late work's.
    let ms: Vec<f64> = out
        .records
        .iter()
        .map(|r| r.estimate.as_ref().unwrap().quality.ms)
        .collect();
    assert_eq!(ms, [1.0, 1.25, 1.25, 1.25, 1.0, 1.0]);
}

#[test]
fn pending_frames_are_sent_as_they_are_when_the_run_ends_or_stops() {
    for (frames, stop_after) in [(3, usize::MAX), (6, 2)] {
        let (seen, out) = run_late(frames, stop_after);
        let statuses: Vec<(usize, TrackStatus)> = seen.iter().map(|s| (s.0, s.1)).collect();
        let lost = TrackStatus::Lost;
        let expected = vec![(0, TrackStatus::Ok), (1, lost), (2, lost)];
        assert_eq!(
            statuses, expected,
            "{frames} frames, stop after {stop_after}"
        );
        assert_eq!(out.summary.lost, 2);
        assert_eq!(out.summary.interrupted, stop_after == 2);
        assert_eq!(out.trajectory.len(), 1);
    }
}

/// `run_observed` shows the observer every frame read, in order, with its estimate; the
/// tracker keeps details only while observed; an observer's error stops the run at that frame
/// with `RunError::Observer`, every earlier record already sent.
#[test]
fn an_observer_sees_each_frame_and_its_error_stops_the_run() {
    let dataset = shared_sequence();
    let mut tracker = direct_tracker(640);
    let mut seen = Vec::new();
    let mut sent = 0;
    let mut sink = |_: &FrameRecord| {
        sent += 1;
        Ok(())
    };
    let mut observer = |o: &Observed<'_>| {
        seen.push((o.index, o.estimate.status, o.frame.image().size()));
        if o.index == 5 {
            Err(io::Error::other("viewer gone"))
        } else {
            Ok(())
        }
    };
    let err = run_observed(
        dataset,
        &mut tracker,
        &RunControl::default(),
        &mut sink,
        &mut observer,
    )
    .expect_err("the observer's error stops the run");
    assert!(
        matches!(err, RunError::Observer { index: 5, .. }),
        "{err:?}"
    );
    assert!(err.to_string().contains("viewer gone"), "{err}");
    assert_eq!(
        seen.iter().map(|s| s.0).collect::<Vec<_>>(),
        (0..=5).collect::<Vec<_>>()
    );
    assert!(seen
        .iter()
        .all(|s| s.1 == TrackStatus::Ok && s.2 == (640, 480)));
    assert_eq!(sent, 5, "frames 0-4 reached the sink");
    assert!(tracker.details().is_none(), "details dropped after the run");
}

/// The monocular and feature RGB-D trackers keep no details until asked; asked, each frame's
/// keypoints come with their roles: in a frame located by PnP its inliers, as many as the
/// estimate counts, and the map's points.
#[test]
fn feature_trackers_show_keypoints_and_map_points_only_when_asked() {
    let dataset = shared_sequence();
    let camera = scaled_camera(640);
    let trackers: [Box<dyn Tracker>; 2] = [
        Box::new(MonoTracker::new(camera, MonoConfig::default()).expect("mono")),
        Box::new(FeatureRgbdTracker::new(camera, FeatureRgbdConfig::default()).expect("rgbd")),
    ];
    for mut tracker in trackers {
        let frame = dataset.load(0).expect("frame 0");
        tracker.track(&frame);
        assert!(tracker.details().is_none());
        tracker.keep_details(true);
        let mut located = 0;
        for i in 1..FRAMES {
            let estimate = tracker.track(&dataset.load(i).expect("frame"));
            let details = tracker.details().expect("details kept");
            assert_eq!(details.keypoints.len(), details.roles.len());
            assert!(!details.keypoints.is_empty(), "frame {i}");
            let (inliers, outliers, _) = details.role_counts();
            // Located by PnP (an initialising frame shows its keypoints unmatched).
            if inliers > 0 {
                located += 1;
                // Matches are one to one between points and keypoints.
                assert_eq!(inliers, estimate.quality.inliers, "frame {i}");
                assert!(
                    outliers < inliers,
                    "frame {i}: {outliers} outliers, {inliers} inliers"
                );
                assert!(details.map_points.len() >= inliers, "frame {i}");
            }
        }
        assert!(located >= FRAMES - 2 - MONO_MAX_INIT_FRAMES, "{located}");
    }
}
