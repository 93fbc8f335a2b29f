//! The full two-view pipeline on random noisy scenes with outliers.

mod common;

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector2, Vector3};
use proptest::prelude::*;
use vofront_geometry::lie::direction_angle_deg;
use vofront_geometry::relative_pose::{estimate_relative_pose, Model, RelativePoseConfig};
use vofront_geometry::triangulate::parallax_deg;
use vofront_geometry::{Camera, CameraError, GeometryError, Pinhole};

/// Pixel noise of the scenes (sigma, pixels).
const NOISE_PX: f64 = 0.5;
/// Rotation error bound for 200 correspondences at 0.5 px noise, up to 50% outliers (100-200
/// inliers): the rotation is partly confounded with the translation in a 63-degree view; the
/// Sampson optimum itself (refined from the truth on the true inliers) is up to 0.5 degrees
/// off on the hardest seeds.
const ROT_BOUND_DEG: f64 = 1.0;
/// Translation direction bound times the median parallax (degrees^2): the direction error
/// grows like noise over parallax (forward motions at 1-2 degrees of parallax reach 6 degrees,
/// 3.6 degrees seen at 3.5 degrees of parallax with 42% outliers).
const DIR_BOUND_DEG2: f64 = 15.0;
/// True median parallax under which a `low_parallax` flag is acceptable (the flag is raised
/// under 1 degree of estimated parallax).
const LOW_PARALLAX_MAX_DEG: f64 = 1.5;
/// Fraction of inliers triangulated: points up to 40 baselines deep at 0.5 px noise can land
/// beyond the 50-baseline far limit or behind a camera.
const MIN_TRIANGULATED: f64 = 0.7;
/// Reprojection bound of the triangulated inliers: the inlier threshold is 1 px on the
/// Sampson distance, the midpoint's reprojection errors stay within a small multiple.
const REPROJ_BOUND_PX: f64 = 3.0;

proptest! {
    #![proptest_config(ProptestConfig::with_cases(vofront_fixtures::proptest_cases(40)))]

    #[test]
    fn general_scene_with_outliers_gives_accurate_pose(seed in 0u64..1_000_000, outliers in 0.0f64..0.5) {
        let scene = common::make_scene(seed, 200, outliers, NOISE_PX, false);
        let rel = estimate_relative_pose(&scene.u1, &scene.u2, &common::camera(), &RelativePoseConfig::default()).unwrap();
        prop_assert_eq!(rel.model, Model::Essential);
        let mut par: Vec<f64> = scene.points.iter().map(|p| parallax_deg(&scene.pose, p)).collect();
        par.sort_by(f64::total_cmp);
        let true_parallax = par[par.len() / 2];
        if rel.low_parallax {
            // Flagged only for genuinely small parallax; the rotation is still accurate.
            prop_assert!(true_parallax < LOW_PARALLAX_MAX_DEG, "{}", true_parallax);
            let rot = rel.rotation().angle_to(&scene.pose.rotation).to_degrees();
            prop_assert!(rot < ROT_BOUND_DEG);
            return Ok(());
        }
        let rot = rel.rotation().angle_to(&scene.pose.rotation).to_degrees();
        prop_assert!(rot < ROT_BOUND_DEG, "rot {} parallax {} inliers {}", rot, rel.parallax_deg, rel.inlier_count());
        let dir = direction_angle_deg(&rel.translation(), &scene.pose.translation.vector);
        prop_assert!(dir < DIR_BOUND_DEG2 / rel.parallax_deg, "dir {} parallax {}", dir, rel.parallax_deg);
        // Inliers: nearly all true inliers, hardly any outlier.
        let true_in = scene.is_inlier.iter().filter(|&&b| b).count();
        let hit = rel.inliers.iter().zip(&scene.is_inlier).filter(|(a, b)| **a && **b).count();
        let false_in = rel.inliers.iter().zip(&scene.is_inlier).filter(|(a, b)| **a && !**b).count();
        prop_assert!(hit as f64 >= 0.8 * true_in as f64, "{} of {}", hit, true_in);
        prop_assert!(false_in as f64 <= 0.05 * scene.u1.len() as f64);
        // Triangulated inliers reproject onto their pixels through the estimated pose.
        let cam = common::camera();
        // (True inliers only: a random match near the epipole can pass the Sampson test while
        // its rays miss each other by more.)
        for (((p, a), b), &true_inlier) in rel.points.iter().zip(&scene.u1).zip(&scene.u2).zip(&scene.is_inlier) {
            if let (Some(p), true) = (p, true_inlier) {
                let e1 = (cam.project(&p.coords).unwrap() - a).norm();
                let e2 = (cam.project(&(rel.pose * p).coords).unwrap() - b).norm();
                prop_assert!(e1 < REPROJ_BOUND_PX && e2 < REPROJ_BOUND_PX, "{} {}", e1, e2);
            }
        }
        prop_assert!(rel.triangulated() as f64 >= MIN_TRIANGULATED * rel.inlier_count() as f64);
    }
}

/// Scene 615734 with 41% outliers (met by the wide exploration `PROPTEST_RNG_SEED=793372`,
/// 4096 cases): one RANSAC sample gave the five-point solver an action matrix on which
/// nalgebra's unbounded Schur QR iteration never returned, so the estimate hung. The bounded
/// iteration drops that sample and the estimate is as accurate as any other.
#[test]
fn a_five_point_sample_whose_qr_iteration_stalls_is_dropped() {
    let scene = common::make_scene(615734, 200, 0.4050609756877926, NOISE_PX, false);
    let rel = estimate_relative_pose(
        &scene.u1,
        &scene.u2,
        &common::camera(),
        &RelativePoseConfig::default(),
    )
    .unwrap();
    let rot = rel.rotation().angle_to(&scene.pose.rotation).to_degrees();
    assert!(rot < ROT_BOUND_DEG, "rotation {rot} deg");
    let dir = direction_angle_deg(&rel.translation(), &scene.pose.translation.vector);
    assert!(
        dir < DIR_BOUND_DEG2 / rel.parallax_deg,
        "direction {dir} deg"
    );
}

#[test]
fn same_seed_gives_same_result() {
    let scene = common::make_scene(7, 200, 0.4, NOISE_PX, false);
    let cfg = RelativePoseConfig::default();
    let a = estimate_relative_pose(&scene.u1, &scene.u2, &common::camera(), &cfg).unwrap();
    let b = estimate_relative_pose(&scene.u1, &scene.u2, &common::camera(), &cfg).unwrap();
    assert_eq!(a, b);
}

/// Planar scenes: the homography must win the model selection and the truth be the pose or,
/// for the two-fold planar ambiguity, its alternative. Statistical floor over fixed seeds: the model
/// selection ratio of ORB-SLAM sits near 0.5 on planes, so a few scenes can fall to the
/// essential side (whose planar solution is unstable).
#[test]
fn planar_scenes_use_the_homography() {
    const SCENES: u64 = 32;
    const MIN_SUCCESS: usize = 26;
    const ROT_DEG: f64 = 1.5;
    let mut ok = 0;
    for seed in 0..SCENES {
        let scene = common::make_scene(1000 + seed, 200, 0.3, NOISE_PX, true);
        let rel = estimate_relative_pose(
            &scene.u1,
            &scene.u2,
            &common::camera(),
            &RelativePoseConfig::default(),
        )
        .unwrap();
        let err = |p: &Isometry3<f64>| p.rotation.angle_to(&scene.pose.rotation).to_degrees();
        let best = rel
            .alternative
            .iter()
            .map(err)
            .fold(err(&rel.pose), f64::min);
        if rel.homography_score_ratio > 0.45 && best < ROT_DEG {
            ok += 1;
        }
    }
    assert!(ok >= MIN_SUCCESS, "{ok} of {SCENES}");
}

#[test]
fn pure_rotation_is_flagged_and_rotation_recovered() {
    for seed in 0..8 {
        let r = UnitQuaternion::from_scaled_axis(Vector3::new(0.03, -0.08, 0.02 * seed as f64));
        let pose = Isometry3::from_parts(Translation3::identity(), r);
        let scene = common::make_scene_with_pose(seed, pose, 200, 0.3, NOISE_PX, false);
        let rel = estimate_relative_pose(
            &scene.u1,
            &scene.u2,
            &common::camera(),
            &RelativePoseConfig::default(),
        )
        .unwrap();
        assert!(rel.low_parallax && rel.pure_rotation, "seed {seed}");
        assert_eq!(rel.translation(), Vector3::zeros());
        assert!(
            rel.rotation().angle_to(&r).to_degrees() < 0.2,
            "{}",
            rel.rotation().angle_to(&r).to_degrees()
        );
    }
}

#[test]
fn bad_input_gives_typed_errors() {
    let cam = common::camera();
    let cfg = RelativePoseConfig::default();
    let p = vec![Vector2::new(100.0, 100.0); 4];
    assert_eq!(
        estimate_relative_pose(&p, &p, &cam, &cfg),
        Err(GeometryError::TooFewCorrespondences { got: 4, need: 5 })
    );
    let scene = common::make_scene(3, 50, 0.0, 0.5, false);
    let mut nan = scene.u1.clone();
    nan[7].x = f64::NAN;
    assert_eq!(
        estimate_relative_pose(&nan, &scene.u2, &cam, &cfg),
        Err(GeometryError::NonFinite)
    );
    let same = vec![Vector2::new(100.0, 100.0); 50];
    assert!(matches!(
        estimate_relative_pose(&same, &scene.u2, &cam, &cfg),
        Err(GeometryError::Degenerate(_))
    ));
    assert!(matches!(
        estimate_relative_pose(&scene.u1, &scene.u2[..49], &cam, &cfg),
        Err(GeometryError::LengthMismatch(50, 49))
    ));
    let zero_f = Camera::pinhole(Pinhole {
        fx: 0.0,
        fy: 520.0,
        cx: 320.0,
        cy: 240.0,
    });
    assert!(matches!(
        estimate_relative_pose(&scene.u1, &scene.u2, &zero_f, &cfg),
        Err(GeometryError::Camera(CameraError::BadFocalLength { .. }))
    ));
    // Pure noise: an error, or a result that explains only a minority of the matches (never
    // a confident wrong pose).
    let noise2: Vec<Vector2<f64>> = scene.u2.iter().rev().copied().collect();
    match estimate_relative_pose(&scene.u1, &noise2, &cam, &cfg) {
        Err(_) => {}
        Ok(rel) => assert!(
            rel.inlier_count() <= noise2.len() / 2,
            "{} of {} random matches called inliers",
            rel.inlier_count(),
            noise2.len()
        ),
    }
}
