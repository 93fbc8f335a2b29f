//! Homography DLT and decomposition on exact planar scenes.

mod common;

use nalgebra::{UnitQuaternion, Vector2, Vector3};
use proptest::prelude::*;
use vofront_geometry::essential::{select_by_chirality, RecoverConfig};
use vofront_geometry::homography::{decompose_homography, homography_dlt, HomographyDecomposition};
use vofront_geometry::lie::direction_angle_deg;

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn decomposition_and_chirality_recover_planar_motion(seed in 0u64..1_000_000) {
        let scene = common::make_scene(seed, 40, 0.0, 0.0, true);
        let x1: Vec<Vector2<f64>> = scene.points.iter().map(|p| p.coords.xy() / p.z).collect();
        let x2: Vec<Vector2<f64>> = scene.points.iter().map(|p| { let q = scene.pose * p; q.coords.xy() / q.z }).collect();
        let h = homography_dlt(&x1, &x2).unwrap();
        let HomographyDecomposition::Motion(cands) = decompose_homography(&h) else {
            return Err(TestCaseError::fail("not a motion"));
        };
        let rt: Vec<_> = cands.iter().map(|(r, t, _)| (*r, *t)).collect();
        let b1: Vec<Vector3<f64>> = x1.iter().map(|p| p.push(1.0)).collect();
        let b2: Vec<Vector3<f64>> = x2.iter().map(|p| p.push(1.0)).collect();
        let rec = select_by_chirality(&rt, &b1, &b2, &vec![true; b1.len()], &RecoverConfig::default()).unwrap();
        prop_assert_eq!(rec.good, b1.len());
        // Two views of a plane can have two motions with every point in front: the truth is
        // then the chosen pose or the runner-up.
        let mut poses = vec![rec.pose];
        if rec.second_good == rec.good {
            poses.extend(rec.runner_up);
        }
        let matches = |p: &nalgebra::Isometry3<f64>| {
            p.rotation.angle_to(&scene.pose.rotation) < 1e-6
                && direction_angle_deg(&p.translation.vector, &scene.pose.translation.vector) < 1e-4
        };
        prop_assert!(poses.iter().any(matches));
    }
}

#[test]
fn pure_rotation_homography_is_reported_as_rotation() {
    let r = UnitQuaternion::from_scaled_axis(Vector3::new(0.02, -0.1, 0.05));
    let x1: Vec<Vector2<f64>> = (0..10)
        .map(|i| Vector2::new((i as f64 * 0.7).sin() * 0.5, (i as f64 * 1.3).cos() * 0.4))
        .collect();
    let x2: Vec<Vector2<f64>> = x1
        .iter()
        .map(|p| {
            let q = r * p.push(1.0);
            q.xy() / q.z
        })
        .collect();
    let h = homography_dlt(&x1, &x2).unwrap();
    match decompose_homography(&h) {
        HomographyDecomposition::Rotation(rot) => {
            assert!(UnitQuaternion::from_rotation_matrix(&rot).angle_to(&r) < 1e-9)
        }
        other => panic!("expected a rotation, got {other:?}"),
    }
}

#[test]
fn collinear_points_give_no_homography() {
    let x1: Vec<Vector2<f64>> = (0..8)
        .map(|i| Vector2::new(i as f64 * 0.1, i as f64 * 0.05))
        .collect();
    assert!(homography_dlt(&x1, &x1).is_none());
}
