//! Minimal and least-squares essential solvers and pose recovery on exact random scenes.

mod common;

use nalgebra::{Matrix3, UnitQuaternion, Vector3};
use proptest::prelude::*;
use vofront_geometry::essential::{
    decompose_essential, essential_5pt, essential_8pt, recover_pose, RecoverConfig,
};
use vofront_geometry::lie::{direction_angle_deg, hat};

/// Bound on the algebraic constraints of a unit-norm five-point solution (exact data, double
/// precision through a 10x10 eigenproblem; spurious roots from nearly complex pairs are the
/// least precise).
const CONSTRAINT_TOL: f64 = 1e-6;
/// Distance (unit Frobenius norm, up to sign) from the true essential matrix.
const TRUTH_TOL: f64 = 1e-5;

fn truth_e(scene: &common::Scene) -> Matrix3<f64> {
    let e = hat(&scene.pose.translation.vector) * scene.pose.rotation.to_rotation_matrix().matrix();
    e / e.norm()
}

fn rays(scene: &common::Scene) -> (Vec<Vector3<f64>>, Vec<Vector3<f64>>) {
    let x1 = scene.points.iter().map(|p| p.coords.normalize()).collect();
    let x2 = scene
        .points
        .iter()
        .map(|p| (scene.pose * p).coords.normalize())
        .collect();
    (x1, x2)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(vofront_fixtures::proptest_cases(64)))]

    #[test]
    fn five_point_solutions_are_essential_and_contain_truth(seed in 0u64..1_000_000) {
        let scene = common::make_scene(seed, 5, 0.0, 0.0, false);
        let (x1, x2) = rays(&scene);
        let a: [Vector3<f64>; 5] = std::array::from_fn(|i| x1[i]);
        let b: [Vector3<f64>; 5] = std::array::from_fn(|i| x2[i]);
        let mut sols = Vec::new();
        essential_5pt(&a, &b, &mut sols);
        prop_assert!(!sols.is_empty() && sols.len() <= 10);
        for e in &sols {
            prop_assert!(e.determinant().abs() < CONSTRAINT_TOL);
            let trace = 2.0 * e * e.transpose() * e - (e * e.transpose()).trace() * e;
            prop_assert!(trace.norm() < CONSTRAINT_TOL, "trace constraint {}", trace.norm());
            for (p, q) in a.iter().zip(&b) {
                prop_assert!(q.dot(&(e * p)).abs() < CONSTRAINT_TOL);
            }
        }
        let t = truth_e(&scene);
        prop_assert!(sols.iter().any(|e| (e - t).norm().min((e + t).norm()) < TRUTH_TOL));
    }

    #[test]
    fn eight_point_recovers_truth_and_chirality_picks_true_pose(seed in 0u64..1_000_000) {
        let scene = common::make_scene(seed, 30, 0.0, 0.0, false);
        let (x1, x2) = rays(&scene);
        let mut sols = Vec::new();
        essential_8pt(&x1, &x2, &mut sols);
        prop_assert_eq!(sols.len(), 1);
        let e = sols[0] / sols[0].norm();
        let t = truth_e(&scene);
        prop_assert!((e - t).norm().min((e + t).norm()) < TRUTH_TOL, "{}", (e - t).norm().min((e + t).norm()));
        // The four candidates contain the truth; chirality keeps it.
        let cands = decompose_essential(&e);
        let close = |r: &nalgebra::Rotation3<f64>| {
            UnitQuaternion::from_rotation_matrix(r).angle_to(&scene.pose.rotation) < 1e-6
        };
        prop_assert!(cands.iter().any(|(r, _)| close(r)));
        let rec = recover_pose(&e, &x1, &x2, &vec![true; x1.len()], &RecoverConfig::default()).unwrap();
        prop_assert_eq!(rec.good, x1.len());
        prop_assert!(rec.pose.rotation.angle_to(&scene.pose.rotation) < 1e-6);
        prop_assert!(direction_angle_deg(&rec.pose.translation.vector, &scene.pose.translation.vector) < 1e-4);
        // Triangulated points are the true ones up to the baseline scale.
        let scale = scene.pose.translation.vector.norm();
        for (p, q) in rec.points.iter().zip(&scene.points) {
            prop_assert!((p.unwrap().coords * scale - q.coords).norm() < 1e-6 * q.coords.norm());
        }
    }
}

#[test]
fn degenerate_five_point_sample_gives_no_solution_or_no_panic() {
    let p = Vector3::new(0.1, 0.2, 1.0);
    let x: [Vector3<f64>; 5] = [p; 5];
    let mut sols = Vec::new();
    essential_5pt(&x, &x, &mut sols);
    assert!(sols.is_empty());
}
