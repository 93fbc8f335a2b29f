//! Bundle adjustment with stereo observations `(u_l, v_l, u_r)` on a synthetic rectified rig
//! with exact ground truth: a perturbed window converges to the truth, the metric scale is
//! recovered with one fixed keyframe (which monocular observations cannot do), and stereo
//! observations without a baseline are refused.

use nalgebra::{Isometry3, Point3, Vector3};
use vofront_geometry::bundle::{bundle_adjust, BundleConfig, BundleProblem, Observation};
use vofront_geometry::{Camera, GeometryError, Pinhole};

/// KITTI-like rig: 0.54 m baseline, 700 px focal length.
const BASELINE: f64 = 0.54;

/// Four keyframes 1 m apart driving along z past 80 points 5-30 m ahead; every keyframe sees
/// every point, exactly, in both images (`stereo`) or in the left one only.
fn window(stereo: bool) -> (BundleProblem, Vec<Isometry3<f64>>, Vec<Point3<f64>>) {
    let camera = Camera::pinhole(Pinhole::new(700.0, 700.0, 620.0, 188.0).unwrap());
    // T_cw of a camera at z = k metres, slightly turning.
    let poses: Vec<Isometry3<f64>> = (0..4)
        .map(|k| {
            let k = k as f64;
            Isometry3::new(Vector3::zeros(), Vector3::new(0.0, 0.01 * k, 0.0))
                * Isometry3::translation(0.0, 0.0, -k)
        })
        .collect();
    let points: Vec<Point3<f64>> = (0..80)
        .map(|j| {
            let f = j as f64;
            Point3::new(
                (f * 0.77).sin() * 6.0,
                (f * 1.31).cos() * 2.0,
                8.0 + 25.0 * (0.5 + 0.5 * (f * 0.43).sin()),
            )
        })
        .collect();
    let mut observations = Vec::new();
    for (i, pose) in poses.iter().enumerate() {
        for (j, p) in points.iter().enumerate() {
            let x = (pose * p).coords;
            let pixel = camera.project(&x).unwrap();
            let right = stereo
                .then(|| camera.project(&(x - Vector3::new(BASELINE, 0.0, 0.0))))
                .flatten()
                .map(|u| u.x);
            observations.push(Observation {
                pose: i,
                point: j,
                pixel,
                sigma: 1.0,
                right,
            });
        }
    }
    let problem = BundleProblem {
        camera,
        poses: poses.clone(),
        points: points.clone(),
        observations,
        baseline: stereo.then_some(BASELINE),
    };
    (problem, poses, points)
}

/// Largest camera-centre error over the keyframes, metres.
fn centre_error(estimated: &[Isometry3<f64>], truth: &[Isometry3<f64>]) -> f64 {
    estimated
        .iter()
        .zip(truth)
        .map(|(e, g)| (e.inverse().translation.vector - g.inverse().translation.vector).norm())
        .fold(0.0, f64::max)
}

/// One fixed keyframe: the stereo rows are the scale's gauge.
fn one_fixed() -> BundleConfig {
    BundleConfig {
        fixed_poses: 1,
        ..BundleConfig::default()
    }
}

#[test]
fn perturbed_stereo_window_converges_to_the_truth() {
    let (mut problem, poses, points) = window(true);
    for (i, pose) in problem.poses.iter_mut().enumerate().skip(1) {
        let i = i as f64;
        *pose = Isometry3::new(
            Vector3::new(0.05 * i, -0.03, 0.08),
            Vector3::new(0.002, -0.003 * i, 0.001),
        ) * *pose;
    }
    for (j, p) in problem.points.iter_mut().enumerate() {
        *p += Vector3::new(0.1, -0.05, if j % 2 == 0 { 0.4 } else { -0.3 });
    }
    let report = bundle_adjust(&mut problem, &one_fixed()).unwrap();
    assert!(report.culled.is_empty(), "{:?}", report.culled);
    assert!(report.rmse_px < 1e-6, "{report:?}");
    assert_eq!(problem.poses[0], poses[0]);
    let error = centre_error(&problem.poses, &poses);
    assert!(error < 1e-6, "centre error {error} m");
    let worst = problem
        .points
        .iter()
        .zip(&points)
        .map(|(e, g)| (e - g).norm())
        .fold(0.0, f64::max);
    assert!(worst < 1e-5, "point error {worst} m");
}

/// Every free camera centre and every point 10% too far from the fixed keyframe: the
/// monocular rows fit that scaled window exactly (scale is not observable), the stereo rows
/// bring it back to metres.
#[test]
fn stereo_rows_recover_the_metric_scale() {
    let scaled = |problem: &mut BundleProblem| {
        for pose in problem.poses.iter_mut().skip(1) {
            pose.translation.vector *= 1.1;
        }
        for p in problem.points.iter_mut() {
            *p = Point3::from(p.coords * 1.1);
        }
    };
    let (mut stereo, poses, _) = window(true);
    scaled(&mut stereo);
    bundle_adjust(&mut stereo, &one_fixed()).unwrap();
    let error = centre_error(&stereo.poses, &poses);
    assert!(error < 1e-6, "stereo centre error {error} m");

    let (mut mono, poses, _) = window(false);
    scaled(&mut mono);
    let report = bundle_adjust(&mut mono, &one_fixed()).unwrap();
    assert!(report.initial_cost < 1e-12, "{report:?}");
    let error = centre_error(&mono.poses, &poses);
    assert!(error > 0.2, "monocular centre error {error} m");
}

#[test]
fn stereo_observations_need_a_positive_baseline() {
    let (mut problem, _, _) = window(true);
    problem.baseline = None;
    assert!(matches!(
        bundle_adjust(&mut problem, &one_fixed()),
        Err(GeometryError::InvalidConfig(_))
    ));
    problem.baseline = Some(-0.5);
    assert!(matches!(
        bundle_adjust(&mut problem, &one_fixed()),
        Err(GeometryError::InvalidConfig(_))
    ));
    problem.baseline = Some(BASELINE);
    problem.observations[5].right = Some(f64::NAN);
    assert_eq!(
        bundle_adjust(&mut problem, &one_fixed()),
        Err(GeometryError::NonFinite)
    );
}
