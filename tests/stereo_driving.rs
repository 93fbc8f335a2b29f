//! The stereo tracker on the rendered driving sequence (10 Hz, 1 m per frame, a straight
//! stretch then the start of a right turn), the right camera rendered `BASELINE` metres to the
//! right of the left one (a rectified rig): every frame is tracked from the first, and the
//! trajectory is metric, SE(3)-aligned to the exact poses with no scale correction. A dataset
//! with one camera is refused with a typed error.

use nalgebra::{Isometry3, Translation3};
use vofront::dataset::{Dataset, Frame};
use vofront::eval::{ate, Alignment, EvalConfig};
use vofront::fixtures::driving::{DrivingSequence, FRAME_RATE};
use vofront::fixtures::image2d::to_gray8;
use vofront::odometry::registry::{OdometryError, Session, TrackerKind};
use vofront::odometry::stereo::{StereoTracker, StereoTrackerConfig};
use vofront::odometry::{TrackStatus, Tracker};
use vofront::trajectory::Trajectory;
use vofront_core::rig::Rig;

/// Frames of the drive.
const FRAMES: usize = 34;
/// Distance between the camera centres, metres (KITTI's is 0.54 m).
const BASELINE: f64 = 0.54;
/// ATE bound, percent of the path length.
const MAX_ATE_PERCENT: f64 = 0.5;
/// Bound on the relative difference of the tracked and the true path lengths.
const MAX_SCALE_ERROR: f64 = 0.005;

fn path_length(poses: &[Isometry3<f64>]) -> f64 {
    poses
        .windows(2)
        .map(|w| (w[1].translation.vector - w[0].translation.vector).norm())
        .sum()
}

#[test]
fn stereo_tracker_follows_the_rendered_drive_in_metres() {
    let seq = DrivingSequence::new(11, FRAMES);
    let right_in_left = Isometry3::from(Translation3::new(BASELINE, 0.0, 0.0));
    let rig =
        Rig::stereo(seq.camera, Isometry3::identity(), seq.camera, right_in_left).expect("rig");
    let mut tracker = StereoTracker::new(rig, StereoTrackerConfig::default()).expect("tracker");
    assert!(tracker.needs_right());
    let (w, h) = seq.size;
    let (mut gt, mut est) = (Trajectory::default(), Trajectory::default());
    let mut poses = Vec::new();
    for (i, pose) in seq.poses_wc.iter().enumerate() {
        let timestamp = i as f64 / FRAME_RATE;
        let right = seq.scene.render(&seq.camera, w, h, &(pose * right_in_left));
        let frame = Frame::new(timestamp, to_gray8(&seq.render(i).image), None)
            .expect("frame")
            .with_right(to_gray8(&right.image))
            .expect("right");
        let e = tracker.track(&frame);
        assert_eq!(e.status, TrackStatus::Ok, "frame {i}: {:?}", e.message);
        if i == 0 {
            assert_eq!(e.pose_wc, Isometry3::identity());
        }
        gt.push(timestamp, seq.poses_wc[0].inverse() * pose);
        est.push(timestamp, e.pose_wc);
        poses.push(e.pose_wc);
    }
    let path = seq.path_length();
    let config = EvalConfig {
        alignment: Alignment::Se3,
        ..EvalConfig::default()
    };
    let ate = ate(&gt, &est, &config).expect("ate").stats.rmse;
    let ate_percent = 100.0 * ate / path;
    let scale_error = (path_length(&poses) / path - 1.0).abs();
    eprintln!("ATE {ate:.4} m ({ate_percent:.3}% of {path:.1} m), scale error {scale_error:.5}");
    assert!(ate_percent < MAX_ATE_PERCENT, "ATE {ate_percent:.3}%");
    assert!(
        scale_error < MAX_SCALE_ERROR,
        "scale error {scale_error:.5}"
    );
}

/// A TUM folder has one camera: the session refuses the stereo method by name.
#[test]
fn a_mono_dataset_is_refused_with_a_typed_error() {
    use vofront::fixtures::scene::{default_camera, room_trajectory, Scene};
    use vofront::fixtures::tum::write_tum_sequence;
    let dir = std::env::temp_dir().join(format!("vofront-stereo-mono-{}", std::process::id()));
    let poses = room_trajectory(3);
    write_tum_sequence(
        &dir,
        &Scene::box_room(2),
        &default_camera(),
        (160, 120),
        &poses,
    )
    .expect("write");
    let dataset = Dataset::open(&dir).expect("open");
    let refused = Session::new(dataset, TrackerKind::Stereo, None);
    std::fs::remove_dir_all(&dir).expect("rm");
    match refused {
        Err(e @ OdometryError::NoStereo { .. }) => {
            assert!(e.to_string().contains("needs a stereo rig"), "{e}")
        }
        other => panic!("expected NoStereo, got {:?}", other.map(|s| s.kind)),
    }
}
