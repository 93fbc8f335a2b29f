//! Sequence trackers on rendered TUM sequences with exact ground truth.

use std::path::PathBuf;
use std::sync::OnceLock;

use vofront::dataset::{Dataset, DatasetError};
use vofront::eval::{ate, Alignment, EvalConfig};
use vofront::fixtures::scene::{default_camera, rescaled_camera, room_trajectory, Scene};
use vofront::fixtures::tum::write_tum_sequence;
use vofront::odometry::direct::{DirectTracker, DirectTrackerConfig};
use vofront::odometry::feature_rgbd::{FeatureRgbdConfig, FeatureRgbdTracker};
use vofront::odometry::mono::{MonoConfig, MonoTracker};
use vofront::odometry::run::{run, RunSummary};
use vofront::odometry::{TrackStatus, Tracker};
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
    let init = status
        .iter()
        .skip(1)
        .position(|s| *s == TrackStatus::Ok)
        .map(|i| i + 1)
        .unwrap();
    assert!(init <= MONO_MAX_INIT_FRAMES, "{status:?}");
    assert!(
        status[init..].iter().all(|s| *s == TrackStatus::Ok),
        "{status:?}"
    );
    let gt = dataset.ground_truth.clone().unwrap();
    let a = ate_rmse(&gt, &out.trajectory, Alignment::Sim3);
    assert!(a < MONO_ATE_M, "ATE {} m", a);
    // A rigid alignment cannot fix the arbitrary scale: the trajectory is not metric.
    let rigid = ate_rmse(&gt, &out.trajectory, Alignment::Se3);
    assert!(rigid > 5.0 * a);
}
