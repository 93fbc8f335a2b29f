//! The monocular tracker on the rendered driving sequence (10 Hz, 1 m per frame, a straight
//! stretch then a 90 degree right turn between facades and parked boxes): every frame is
//! tracked (the frames the initialisation waits through are located late, once its map exists)
//! and the Sim(3)-aligned trajectory stays within 0.5% of the path length, issue 13's target
//! (measured: 0.33% over every frame and 0.26% to 0.33% over RANSAC seeds 0-11; 0.35% and
//! 0.22% to 0.93% before a located pose that moved the points by half the matching window was
//! matched again around itself; earlier, over the frames after the initialisation, 0.33% with
//! three keyframes fixed in the local bundle adjustment, 0.48% with two, 0.31% before the
//! adjustment's gate was floored at half a pixel, 0.60% before keypoint-level noise scales and
//! level prediction, 1.05% before the local bundle adjustment). The rendered corners are more
//! precise than real ones: over RANSAC seeds 0-7 the floor raised this sequence's median from
//! 0.37% to 0.46%, while on the real KITTI clips it lowered every median (`kitti_06` ATE 0.145
//! -> 0.092 m over 12 seeds); the third fixed keyframe lowered it to 0.40% (worst seed 1.25% ->
//! 0.70%). After a segment break the new map keeps the speed of the old one.

use vofront::dataset::{Dataset, Frame};
use vofront::eval::{ate, rpe, Alignment, EvalConfig};
use vofront::fixtures::driving::{DrivingSequence, FRAME_RATE};
use vofront::fixtures::image2d::to_gray8;
use vofront::image::Image;
use vofront::odometry::mono::{MonoConfig, MonoTracker};
use vofront::odometry::{TrackStatus, Tracker};
use vofront::robust::median_in_place;
use vofront::trajectory::Trajectory;

/// Frames of the sequence: 24 m straight, then the turn (about 4 degrees per frame).
const FRAMES: usize = 44;
/// Frames the tracker may wait for parallax before the map exists.
const MAX_INIT_FRAMES: usize = 4;
/// ATE bound, percent of the path length.
const MAX_ATE_PERCENT: f64 = 0.5;

#[test]
fn mono_tracker_follows_the_rendered_drive() {
    let seq = DrivingSequence::new(11, FRAMES);
    let mut tracker = MonoTracker::new(seq.camera, MonoConfig::default()).expect("tracker");
    let mut estimates = Vec::new();
    let mut late = Vec::new();
    let mut gt = Trajectory::default();
    for (i, pose) in seq.poses_wc.iter().enumerate() {
        let timestamp = i as f64 / FRAME_RATE;
        let frame = Frame::new(timestamp, to_gray8(&seq.render(i).image), None).expect("frame");
        estimates.push(tracker.track(&frame));
        for (back, e) in tracker.revised() {
            assert_eq!(
                estimates[i - back].status,
                TrackStatus::Lost,
                "frame {}",
                i - back
            );
            late.push(i - back);
            estimates[i - back] = e;
        }
        gt.push(timestamp, *pose);
    }
    // The frames the initialisation waited through are located late; then every frame is
    // tracked, none restarted.
    assert!(late.len() < MAX_INIT_FRAMES, "waited through {late:?}");
    let mut est = Trajectory::default();
    for (i, e) in estimates.iter().enumerate() {
        assert_eq!(e.status, TrackStatus::Ok, "frame {i}: {:?}", e.message);
        est.push(i as f64 / FRAME_RATE, e.pose_wc);
    }
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
    let blank = || Image::filled(w as usize, h as usize, 128u8);
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

/// Issue 13: after a loss the new map shares nothing with the lost one (the street is
/// retextured: no old point can be matched), so its scale cannot be joined by points. It is
/// set from the motion model instead: the steps of the new segment have the length of the
/// old segment's steps, where a unit baseline would make them arbitrary.
#[test]
fn a_segment_break_keeps_the_speed_of_the_motion_model() {
    const FRAMES: usize = 24;
    let before = DrivingSequence::new(21, FRAMES);
    let after = DrivingSequence::new(22, FRAMES);
    let (w, h) = before.size;
    let blank = || Image::filled(w as usize, h as usize, 128u8);
    let mut tracker = MonoTracker::new(before.camera, MonoConfig::default()).expect("tracker");
    let estimates: Vec<_> = (0..FRAMES)
        .map(|i| {
            let image = match i {
                0..10 => to_gray8(&before.render(i).image),
                10..12 => blank(),
                _ => to_gray8(&after.render(i).image),
            };
            let frame = Frame::new(i as f64 / FRAME_RATE, image, None).expect("frame");
            tracker.track(&frame)
        })
        .collect();
    let restart = (12..FRAMES)
        .find(|&i| estimates[i].status == TrackStatus::Reinitialised)
        .expect("a new map after the blank frames");
    let message = estimates[restart].message.clone().unwrap_or_default();
    assert!(message.contains("segment break"), "{message}");
    assert!(message.contains("motion model"), "{message}");
    // Step lengths (map units per frame) of consecutive tracked frames in each segment.
    let steps = |range: std::ops::Range<usize>| -> Vec<f64> {
        range
            .filter(|&i| estimates[i - 1].status != TrackStatus::Lost)
            .filter(|&i| estimates[i].status != TrackStatus::Lost)
            .map(|i| {
                (estimates[i].pose_wc.translation.vector
                    - estimates[i - 1].pose_wc.translation.vector)
                    .norm()
            })
            .collect()
    };
    let median = |mut v: Vec<f64>| median_in_place(&mut v).expect("tracked steps");
    let old = median(steps(MAX_INIT_FRAMES + 2..10));
    let new = median(steps(restart + 1..FRAMES));
    let ratio = new / old;
    assert!(
        (0.8..1.25).contains(&ratio),
        "steps {new:.4} after the break, {old:.4} before (ratio {ratio:.3})"
    );
}

/// Issue 13: the start of the turn, 4 degrees of yaw the constant-velocity prediction did not
/// expect (about 25 px, the matching window's width), is located as precisely as the straight
/// road before it. The window lets through only a part of the right matches, biased towards
/// the prediction, and the pose found from them turned by only 2.2 to 3.4 of the 4.1 degrees
/// on most RANSAC seeds (with a third of the usual inliers), until a pose that moved the
/// points by half the window or more was matched again around itself.
#[test]
fn the_start_of_a_turn_is_located_as_precisely_as_the_straight() {
    const FRAMES: usize = 30;
    /// Largest per-frame rotation error, degrees (the frames before the turn stay within 0.2).
    const MAX_ROTATION_ERROR_DEG: f64 = 0.3;
    let seq = DrivingSequence::new(11, FRAMES);
    let images: Vec<_> = (0..FRAMES)
        .map(|i| to_gray8(&seq.render(i).image))
        .collect();
    for seed in 0..4 {
        let mut cfg = MonoConfig::default();
        cfg.relative.ransac.seed = seed;
        cfg.pnp.ransac.seed = seed;
        let mut tracker = MonoTracker::new(seq.camera, cfg).expect("tracker");
        let estimates: Vec<_> = images
            .iter()
            .enumerate()
            .map(|(i, image)| {
                let frame = Frame::new(i as f64 / FRAME_RATE, image.clone(), None).expect("frame");
                tracker.track(&frame)
            })
            .collect();
        let turn = (1..FRAMES)
            .find(|&i| seq.relative(i - 1, i).rotation.angle() > 1f64.to_radians())
            .expect("the sequence turns");
        for i in turn - 3..FRAMES {
            assert_eq!(
                estimates[i].status,
                TrackStatus::Ok,
                "seed {seed}, frame {i}"
            );
            let truth = seq.relative(i - 1, i).rotation;
            let est = (estimates[i].pose_wc.inverse() * estimates[i - 1].pose_wc).rotation;
            let error = truth.angle_to(&est).to_degrees();
            assert!(
                error <= MAX_ROTATION_ERROR_DEG,
                "seed {seed}, frame {i}: rotation off by {error:.2} deg ({:.2} of {:.2})",
                est.angle().to_degrees(),
                truth.angle().to_degrees()
            );
        }
    }
}

/// Issue 34: at a third of the frame rate, a frame of the real `kitti_06` clip (3.6 m between
/// frames past near facades and trees) loses half of the keyframe's points, and the next then
/// found too few to be located: over RANSAC seeds 0-11, seven lost four frames and restarted
/// with a segment break. The tracker now takes a keyframe when the next frame is forecast to
/// track fewer points than a keyframe needs (`keyframe::forecast_tracked`): every frame is
/// posed, none restarted. Skipped when the shared data are absent.
#[test]
fn every_third_frame_of_kitti_06_is_tracked_without_a_restart() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/kitti_06");
    if !dir.exists() {
        eprintln!("skipped: {} not found", dir.display());
        return;
    }
    let dataset = Dataset::open(&dir).expect("kitti_06");
    let camera = dataset.camera.expect("calibration");
    let frames: Vec<Frame> = (0..dataset.len())
        .step_by(3)
        .map(|i| dataset.load(i).expect("frame"))
        .collect();
    for seed in 0..12 {
        let mut cfg = MonoConfig::default();
        cfg.relative.ransac.seed = seed;
        cfg.pnp.ransac.seed = seed;
        let mut tracker = MonoTracker::new(camera, cfg).expect("tracker");
        let mut estimates = Vec::new();
        for (k, frame) in frames.iter().enumerate() {
            estimates.push(tracker.track(frame));
            for (back, e) in tracker.revised() {
                estimates[k - back] = e;
            }
        }
        for (k, e) in estimates.iter().enumerate() {
            assert_eq!(
                e.status,
                TrackStatus::Ok,
                "seed {seed}, frame {}: {:?}",
                3 * k,
                e.message
            );
        }
    }
}
