//! Two-view and PnP estimates on points seen through a Kannala-Brandt fisheye lens.
//!
//! The pixels are exact projections through the lens (plus noise); the estimators only see the
//! camera, so they must undistort with the right model to recover the true pose.

mod common;

use nalgebra::{Isometry3, Point3, Vector2, Vector3};
use proptest::prelude::*;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use vofront_geometry::camera::{Camera, KannalaBrandt, Pinhole};
use vofront_geometry::pnp::{solve_pnp_ransac, PnpConfig};
use vofront_geometry::relative_pose::{estimate_relative_pose, RelativePoseConfig};

/// A 512 x 512 fisheye with TUM-VI-like intrinsics and coefficients (about 190 px per radian).
fn fisheye() -> Camera {
    Camera::new(
        Pinhole::new(190.98, 190.97, 254.93, 256.90).unwrap(),
        KannalaBrandt::new([0.0034, 0.0007, -0.0021, 0.0002]).unwrap(),
    )
}

/// The same intrinsics read as an ideal pinhole: the wrong model for [`fisheye`] pixels.
fn as_pinhole() -> Camera {
    Camera::pinhole(fisheye().pinhole)
}

/// A camera-frame point on a ray up to `max_theta` radians off the axis, 2-8 m away.
fn wide_point(rng: &mut StdRng, max_theta: f64) -> Point3<f64> {
    let theta = rng.random_range(0.0..max_theta);
    let phi = rng.random_range(-std::f64::consts::PI..std::f64::consts::PI);
    let depth = rng.random_range(2.0..8.0);
    Point3::from(
        depth
            * Vector3::new(
                theta.sin() * phi.cos(),
                theta.sin() * phi.sin(),
                theta.cos(),
            ),
    )
}

/// The pixel of `p` through `cam` with Gaussian noise `sigma`, `None` outside the image.
fn observe(cam: &Camera, p: &Point3<f64>, rng: &mut StdRng, sigma: f64) -> Option<Vector2<f64>> {
    let u = cam.project(&p.coords)? + Vector2::new(common::gauss(rng), common::gauss(rng)) * sigma;
    (u.x >= 0.0 && u.y >= 0.0 && u.x <= 511.0 && u.y <= 511.0).then_some(u)
}

/// Rotation (degrees) and translation (metres) error of `est` against `truth`.
fn pose_error(est: &Isometry3<f64>, truth: &Isometry3<f64>) -> (f64, f64) {
    (
        est.rotation.angle_to(&truth.rotation).to_degrees(),
        (est.translation.vector - truth.translation.vector).norm(),
    )
}

/// `(T_cw, world points, fisheye pixels)`: 150 points over a 140-degree field, 0.3 px noise,
/// the first 20% replaced by random pixels.
fn pnp_scene(seed: u64) -> (Isometry3<f64>, Vec<Point3<f64>>, Vec<Vector2<f64>>) {
    let mut rng = StdRng::seed_from_u64(seed);
    let cam = fisheye();
    let t_cw = common::random_pose(&mut rng, 0.5, 1.0);
    let (mut world, mut pixels) = (Vec::new(), Vec::new());
    while world.len() < 150 {
        let pc = wide_point(&mut rng, 70f64.to_radians());
        let Some(u) = observe(&cam, &pc, &mut rng, 0.3) else {
            continue;
        };
        let u = if world.len() < 30 {
            Vector2::new(rng.random_range(0.0..511.0), rng.random_range(0.0..511.0))
        } else {
            u
        };
        world.push(t_cw.inverse() * pc);
        pixels.push(u);
    }
    (t_cw, world, pixels)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(vofront_fixtures::proptest_cases(12)))]

    /// Bounds: 0.3 px at ~190 px/rad is ~0.1 mrad per point; with 120 inliers the pose is good
    /// to a few hundredths of a degree and millimetres, the bounds leave a factor ~5.
    #[test]
    fn pnp_on_fisheye_pixels_recovers_the_pose(seed in 0u64..1_000_000) {
        let (t_cw, world, pixels) = pnp_scene(seed);
        let fit = solve_pnp_ransac(&world, &pixels, &fisheye(), None, &PnpConfig::default()).unwrap();
        let meets_bounds = |fit: &vofront_geometry::pnp::PnpResult| {
            let (rot, trans) = pose_error(&fit.pose, &t_cw);
            rot < 0.2 && trans < 0.03 && fit.inlier_count() >= 110
        };
        let (rot, trans) = pose_error(&fit.pose, &t_cw);
        prop_assert!(rot < 0.2 && trans < 0.03, "rotation {rot} deg, translation {trans} m");
        prop_assert!(fit.inlier_count() >= 110, "{} inliers", fit.inlier_count());
        // Read with the wrong (pinhole) model the same pixels fail those bounds: the centre of
        // the image (where tan(theta) is close to theta) can still give a fair pose from half
        // the points, but not the full support and accuracy.
        let wrong = solve_pnp_ransac(&world, &pixels, &as_pinhole(), None, &PnpConfig::default());
        prop_assert!(wrong.map_or(true, |w| !meets_bounds(&w)));
    }

    /// 200 points seen from both frames through the fisheye lens, 0.3 px noise, 10% outliers.
    /// Bounds: over 150 seeds the rotation error has median 0.07 deg, 95th percentile 0.14 deg
    /// and maximum 0.21 deg; the wide exploration (4096 cases) met 0.31 deg (seed 962824, the
    /// same for every RANSAC seed: the optimum of that noise draw), so 0.4 deg; the direction
    /// bound is the same spread at the 2-6 deg parallax of these scenes.
    #[test]
    fn relative_pose_on_fisheye_pixels_recovers_the_motion(seed in 0u64..1_000_000) {
        let mut rng = StdRng::seed_from_u64(seed);
        let cam = fisheye();
        let t_21 = common::random_pose(&mut rng, 0.3, 0.5);
        let (mut u1, mut u2) = (Vec::new(), Vec::new());
        while u1.len() < 200 {
            let p1 = wide_point(&mut rng, 65f64.to_radians());
            let (Some(a), Some(b)) = (observe(&cam, &p1, &mut rng, 0.3), observe(&cam, &(t_21 * p1), &mut rng, 0.3)) else {
                continue;
            };
            let b = if u1.len() < 20 {
                Vector2::new(rng.random_range(0.0..511.0), rng.random_range(0.0..511.0))
            } else {
                b
            };
            u1.push(a);
            u2.push(b);
        }
        let fit = estimate_relative_pose(&u1, &u2, &cam, &RelativePoseConfig::default()).unwrap();
        let rot = fit.pose.rotation.angle_to(&t_21.rotation).to_degrees();
        let direction = fit.pose.translation.vector.normalize().dot(&t_21.translation.vector.normalize()).clamp(-1.0, 1.0).acos().to_degrees();
        prop_assert!(rot < 0.4 && direction < 3.0, "rotation {rot} deg, direction {direction} deg");
    }
}
