//! The tracker's recovery paths, driven on the rendered street drive, and its map rules.

use std::error::Error;
use std::time::Instant;

use vofront_core::lie::direction_angle_deg;
use vofront_features::{Descriptor, Features};
use vofront_fixtures::driving::{DrivingSequence, FRAME_RATE};
use vofront_fixtures::image2d::to_gray8;

use super::init::initialise;
use super::{MonoConfig, MonoTracker, State};
use crate::dataset::Frame;
use crate::odometry::local_map::{predicted_level, MapPoint};
use crate::odometry::{TrackStatus, Tracker};

type TestResult = Result<(), Box<dyn Error>>;

/// Finest-level keypoints at `(xs, ys)` with the given descriptors (scale 1, no angle).
pub(super) fn level0_features(
    xs: Vec<f32>,
    ys: Vec<f32>,
    descriptors: Vec<Descriptor>,
) -> Result<Features, vofront_features::FeatureError> {
    let n = xs.len();
    Features::new(
        xs,
        ys,
        vec![0; n],
        vec![1.0; n],
        vec![0.0; n],
        vec![1.0; n],
        descriptors,
    )
}

/// A linear congruential generator from `seed`: uniform in `[0, 1)`.
fn uniform_from(seed: u64) -> impl FnMut() -> f64 {
    let mut state = seed;
    move || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (state >> 40) as f64 / (1u64 << 24) as f64
    }
}

/// `n` distinct descriptors: each matches only its own copy exactly.
fn distinct_descriptors(n: usize) -> Vec<Descriptor> {
    (0..n as u64)
        .map(|j| Descriptor([j.wrapping_mul(0x9e37_79b9_7f4a_7c15), j, !j, j << 7]))
        .collect()
}

/// When tracking against the map fails, the frame is not lost: a new map is made at once
/// from it and a keyframe of the window, placed at that keyframe's pose with the old map's
/// scale, and the next frame is tracked on it.
#[test]
fn a_failed_frame_restarts_from_a_window_keyframe_with_the_map_scale() -> TestResult {
    let drive = DrivingSequence::new(11, 12);
    let frame = |i: usize| {
        let image = to_gray8(&drive.render(i).image);
        Frame::new(i as f64 / FRAME_RATE, image, None)
    };
    let mut tracker = MonoTracker::new(drive.camera, MonoConfig::default())?;
    let mut poses = Vec::new();
    for i in 0..10 {
        poses.push(tracker.track(&frame(i)?).pose_wc);
    }
    let State::Tracking { map, .. } = std::mem::replace(&mut tracker.state, State::Empty) else {
        return Err("not tracking after ten frames".into());
    };
    // Frame 10, as if its tracking had failed.
    let current = tracker.orb.detect_and_describe(frame(10)?.image())?;
    tracker.lost.lose(map, tracker.coast.motion.step_length());
    let Some(restart) = tracker.restart_from_window(&current, Instant::now()) else {
        return Err("no window keyframe initialised with frame 10".into());
    };
    tracker.late.end_frame();
    assert_eq!(restart.status, TrackStatus::Reinitialised);
    let message = restart.message.clone().unwrap_or_default();
    assert!(message.contains("joined to the lost one"), "{message}");
    // The step 9 -> 10 has the direction of the true one (the tracked steps before it are 1-7
    // degrees off: 0.3 map units between frames a few centimetres apart in error) and the
    // length of the map's earlier steps (the scale is kept). The tracker's world is the first
    // camera's frame.
    let true_wc = |i: usize| drive.poses_wc[0].inverse() * drive.poses_wc[i];
    let step = restart.pose_wc.translation.vector - poses[9].translation.vector;
    let truth = true_wc(10).translation.vector - true_wc(9).translation.vector;
    let angle = direction_angle_deg(&step, &truth);
    assert!(angle < 10.0, "step direction {angle} deg off");
    let mut before: Vec<f64> = (5..10)
        .map(|i| (poses[i].translation.vector - poses[i - 1].translation.vector).norm())
        .collect();
    let median = crate::robust::median_in_place(&mut before).ok_or("no steps")?;
    let ratio = step.norm() / median;
    assert!((0.8..1.25).contains(&ratio), "step length ratio {ratio}");
    // The next frame tracks on the new map.
    assert_eq!(tracker.track(&frame(11)?).status, TrackStatus::Ok);
    Ok(())
}

/// A point whose descriptor was taken at level 2 from 10 map units is expected two levels up
/// from 10 / 1.2^2 (it looks 1.44 times larger), one level down from 12, and within ORB's
/// level range from far away or very near.
#[test]
fn the_expected_level_follows_the_distance_to_the_point() {
    let point = MapPoint {
        position: nalgebra::Point3::origin(),
        descriptor: Descriptor([0; 4]),
        level: 2,
        recent: None,
        distance: 10.0,
        observations: Vec::new(),
        covariance: None,
        visible: 1,
        found: 1,
    };
    assert_eq!(predicted_level(&point, 10.0, 1.2), 2);
    assert_eq!(predicted_level(&point, 10.0 / 1.44, 1.2), 4);
    assert_eq!(predicted_level(&point, 12.0, 1.2), 1);
    assert_eq!(predicted_level(&point, 1e6, 1.2), 0);
    assert_eq!(predicted_level(&point, 1e-9, 1.2), 31);
    assert_eq!(predicted_level(&point, 0.0, 1.2), 2);
}

/// 300 features whose descriptors match one to one between the frames but whose positions are
/// unrelated (random matches): no two-view pose is trusted, so no map is made, and the
/// reference is given up rather than waited on.
#[test]
fn random_matches_make_no_map() -> TestResult {
    let drive = DrivingSequence::new(3, 1);
    let (w, h) = (drive.size.0 as f32, drive.size.1 as f32);
    let mut uniform = uniform_from(5);
    let mut features = || {
        let n = 300;
        let xs = (0..n).map(|_| uniform() as f32 * w).collect();
        let ys = (0..n).map(|_| uniform() as f32 * h).collect();
        let descriptors = distinct_descriptors(n);
        level0_features(xs, ys, descriptors)
    };
    let (reference, current) = (features()?, features()?);
    let tracker = MonoTracker::new(drive.camera, MonoConfig::default())?;
    let rules = tracker.init_rules();
    let t_w1 = nalgebra::Isometry3::identity();
    match initialise(&rules, &reference, &t_w1, &current, (0, 1)) {
        Ok((map, ..)) => {
            Err(format!("a map of {} points from random matches", map.points.len()).into())
        }
        Err(failure) => {
            assert!(!failure.keep_reference, "{}", failure.why);
            Ok(())
        }
    }
}

/// A two-view pose judged unreliable makes no map and keeps its reference: 120 true
/// correspondences seen with several degrees of parallax, among 600 random ones (an inlier
/// ratio of 0.17, under the quality record's 0.25 even with the random ones that fall near an
/// epipolar line by chance). The true ones alone make the map.
#[test]
fn an_unreliable_two_view_pose_waits_instead_of_making_a_map() -> TestResult {
    let drive = DrivingSequence::new(3, 1);
    let camera = drive.camera;
    let (w, h) = (drive.size.0 as f64, drive.size.1 as f64);
    let mut uniform = uniform_from(11);
    let t_wc2 = nalgebra::Isometry3::new(
        nalgebra::Vector3::new(1.5, 0.0, 0.5),
        nalgebra::Vector3::new(0.0, -0.05, 0.0),
    );
    let (mut x1, mut x2) = (Vec::new(), Vec::new());
    while x1.len() < 120 {
        let p = nalgebra::Point3::new(
            12.0 * uniform() - 6.0,
            4.0 * uniform() - 2.0,
            8.0 + 12.0 * uniform(),
        );
        let seen = camera
            .project(&p.coords)
            .zip(camera.project(&(t_wc2.inverse() * p).coords));
        if let Some((u1, u2)) = seen.filter(|(u1, u2)| {
            [u1, u2]
                .iter()
                .all(|u| u.x >= 0.0 && u.y >= 0.0 && u.x < w && u.y < h)
        }) {
            x1.push(u1);
            x2.push(u2);
        }
    }
    let true_pairs = x1.len();
    for _ in 0..600 {
        x1.push(nalgebra::Vector2::new(uniform() * w, uniform() * h));
        x2.push(nalgebra::Vector2::new(uniform() * w, uniform() * h));
    }
    let features = |xs: &[nalgebra::Vector2<f64>], n: usize| {
        let descriptors = distinct_descriptors(n);
        level0_features(
            xs[..n].iter().map(|u| u.x as f32).collect(),
            xs[..n].iter().map(|u| u.y as f32).collect(),
            descriptors,
        )
    };
    let tracker = MonoTracker::new(camera, MonoConfig::default())?;
    let rules = tracker.init_rules();
    let t_w1 = nalgebra::Isometry3::identity();
    let all = (features(&x1, x1.len())?, features(&x2, x2.len())?);
    match initialise(&rules, &all.0, &t_w1, &all.1, (0, 1)) {
        Ok((map, ..)) => {
            return Err(format!("a map of {} points from 17% inliers", map.points.len()).into())
        }
        Err(failure) => {
            assert!(failure.keep_reference, "{}", failure.why);
            assert!(failure.why.contains("unreliable"), "{}", failure.why);
        }
    }
    let clean = (features(&x1, true_pairs)?, features(&x2, true_pairs)?);
    let Ok((map, ..)) = initialise(&rules, &clean.0, &t_w1, &clean.1, (0, 1)) else {
        return Err("the true correspondences alone make no map".into());
    };
    assert!(map.points.len() >= 100, "{} points", map.points.len());
    Ok(())
}
