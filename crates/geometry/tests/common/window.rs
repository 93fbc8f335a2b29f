//! A keyframe window with exact ground truth for the bundle-adjustment tests and benchmark:
//! a camera moving forward through a field of points, seen with Gaussian pixel noise and
//! optional gross outliers.
#![allow(dead_code)]

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector2, Vector3};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use vofront_geometry::bundle::{BundleProblem, Observation};
use vofront_geometry::{Camera, Pinhole};

/// Image size of the window's camera, pixels.
pub const SIZE: (f64, f64) = (640.0, 480.0);

/// The window and its truth.
pub struct Window {
    /// Noisy observations, poses and points at the truth.
    pub problem: BundleProblem,
    /// True `T_cw` per keyframe.
    pub poses: Vec<Isometry3<f64>>,
    /// True world points.
    pub points: Vec<Point3<f64>>,
    /// True for observations replaced by gross outliers.
    pub outlier: Vec<bool>,
}

pub use vofront_fixtures::noise::gauss;

/// Camera centre of keyframe `k`: 0.25 m forward per keyframe with a sideways weave.
pub fn centre(k: usize) -> Vector3<f64> {
    let f = k as f64;
    Vector3::new(0.2 * (0.9 * f).sin(), 0.02 * f, 0.25 * f)
}

/// `keyframes` poses along [`centre`] with a slow yaw, `points` points 4..14 m ahead, pixel
/// noise `noise_px` per coordinate and a fraction `outliers` of the observations moved by
/// 15..60 pixels in a random direction.
pub fn forward_window(
    seed: u64,
    keyframes: usize,
    points: usize,
    noise_px: f64,
    outliers: f64,
) -> Window {
    let mut rng = StdRng::seed_from_u64(seed);
    let camera = Camera::pinhole(Pinhole::new(500.0, 500.0, 319.5, 239.5).expect("valid"));
    let poses: Vec<Isometry3<f64>> = (0..keyframes)
        .map(|k| {
            let yaw = UnitQuaternion::from_scaled_axis(Vector3::y() * 0.01 * k as f64);
            Isometry3::from_parts(Translation3::from(centre(k)), yaw).inverse()
        })
        .collect();
    let world: Vec<Point3<f64>> = (0..points)
        .map(|_| {
            Point3::new(
                rng.random_range(-5.0..5.0),
                rng.random_range(-3.5..3.5),
                rng.random_range(4.0..14.0),
            )
        })
        .collect();
    let mut observations = Vec::new();
    let mut outlier = Vec::new();
    for (i, pose) in poses.iter().enumerate() {
        for (j, p) in world.iter().enumerate() {
            let Some(u) = camera.project(&(pose * p).coords) else {
                continue;
            };
            if !(u.x >= 0.0 && u.y >= 0.0 && u.x <= SIZE.0 - 1.0 && u.y <= SIZE.1 - 1.0) {
                continue;
            }
            let mut pixel = u + Vector2::new(gauss(&mut rng), gauss(&mut rng)) * noise_px;
            let bad = rng.random_range(0.0..1.0) < outliers;
            if bad {
                let angle = rng.random_range(0.0..std::f64::consts::TAU);
                pixel += Vector2::new(angle.cos(), angle.sin()) * rng.random_range(15.0..60.0);
            }
            observations.push(Observation {
                pose: i,
                point: j,
                pixel,
                sigma: 1.0,
                right: None,
            });
            outlier.push(bad);
        }
    }
    Window {
        problem: BundleProblem {
            camera,
            poses: poses.clone(),
            points: world.clone(),
            observations,
            baseline: None,
        },
        poses,
        points: world,
        outlier,
    }
}

/// Moves every pose after the first `fixed` by a random left increment (rotation up to
/// `angle` rad, translation `shift` m) and every point by Gaussian noise of `point_sigma` m.
pub fn perturb(
    problem: &mut BundleProblem,
    seed: u64,
    fixed: usize,
    angle: f64,
    shift: f64,
    point_sigma: f64,
) {
    let mut rng = StdRng::seed_from_u64(seed);
    let unit = |rng: &mut StdRng| Vector3::new(gauss(rng), gauss(rng), gauss(rng)).normalize();
    for pose in problem.poses.iter_mut().skip(fixed) {
        let (axis, dir) = (unit(&mut rng), unit(&mut rng));
        let delta = Isometry3::from_parts(
            Translation3::from(dir * shift),
            UnitQuaternion::from_scaled_axis(axis * angle),
        );
        *pose = delta * *pose;
    }
    for p in &mut problem.points {
        *p += Vector3::new(gauss(&mut rng), gauss(&mut rng), gauss(&mut rng)) * point_sigma;
    }
}
