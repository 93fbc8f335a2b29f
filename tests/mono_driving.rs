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
        let frame = Frame::new(timestamp, to_gray8(&seq.render(i).image), None).expect("frame");
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

/// Issue 11: a featureless frame is skipped, never waited on. A blank frame before and during
/// the initialisation must not become the reference (the map is made from the textured frames
/// around it), and a blank frame while tracking is recovered from within a few frames.
#[test]
fn featureless_frames_are_skipped_not_waited_on() {
    let seq = DrivingSequence::new(12, 12);
    let (w, h) = seq.size;
    let blank = || image::GrayImage::from_pixel(w, h, image::Luma([128]));
    let rendered = |i: usize| to_gray8(&seq.render(i).image);
    // blank, r0, blank, r1 .. r6, blank, r7 .. r11
    let mut order: Vec<Option<usize>> = vec![None, Some(0), None];
    order.extend((1..7).map(Some));
    order.push(None);
    order.extend((7..12).map(Some));
    let mut tracker = MonoTracker::new(seq.camera, MonoConfig::default()).expect("tracker");
    let statuses: Vec<TrackStatus> = order
        .iter()
        .enumerate()
        .map(|(k, which)| {
            let image = which.map_or_else(blank, rendered);
            let frame = Frame::new(k as f64 / FRAME_RATE, image, None).expect("frame");
            tracker.track(&frame).status
        })
        .collect();
    // The blank first frame is skipped; r0 starts the world frame.
    assert_eq!(statuses[0], TrackStatus::Lost);
    assert_eq!(statuses[1], TrackStatus::Ok);
    // The map is made from r0 within the usual few frames, despite the blank in between.
    let initialised = (3..9).find(|&k| statuses[k] == TrackStatus::Ok);
    assert!(initialised.is_some(), "{statuses:?}");
    // After the blank during tracking (index 9) tracking resumes within five frames.
    assert!(
        (10..15).any(|k| statuses[k] != TrackStatus::Lost),
        "{statuses:?}"
    );
}
