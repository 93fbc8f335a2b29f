//! Random two-view scenes shared by the integration tests.
#![allow(dead_code)]

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector2, Vector3};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use vofront_geometry::{Camera, Pinhole};

/// Camera of the tests (TUM-like, distortion-free).
pub fn camera() -> Camera {
    Camera::pinhole(Pinhole::new(520.0, 520.0, 320.0, 240.0).expect("valid intrinsics"))
}

/// A random scene: `T_21`, points in camera 1 visible in both images.
pub struct Scene {
    /// Ground truth `T_21`.
    pub pose: Isometry3<f64>,
    /// Points in camera 1.
    pub points: Vec<Point3<f64>>,
    /// Pixels in image 1 (noisy, with outliers).
    pub u1: Vec<Vector2<f64>>,
    /// Pixels in image 2 (noisy, with outliers).
    pub u2: Vec<Vector2<f64>>,
    /// True for inlier correspondences.
    pub is_inlier: Vec<bool>,
}

pub use vofront_fixtures::noise::gauss;

/// Random pose with rotation angle up to `max_angle` rad and translation of length `baseline`.
pub fn random_pose(rng: &mut StdRng, max_angle: f64, baseline: f64) -> Isometry3<f64> {
    let axis = Vector3::new(gauss(rng), gauss(rng), gauss(rng)).normalize();
    let angle = rng.random_range(0.0..max_angle);
    let dir = Vector3::new(gauss(rng), gauss(rng), gauss(rng)).normalize();
    Isometry3::from_parts(
        Translation3::from(dir * baseline),
        UnitQuaternion::from_scaled_axis(axis * angle),
    )
}

/// Builds a scene of `n` correspondences, `outlier_ratio` of them random, with Gaussian
/// pixel noise `sigma`; `planar` puts the points on a plane.
pub fn make_scene(seed: u64, n: usize, outlier_ratio: f64, sigma: f64, planar: bool) -> Scene {
    let mut rng = StdRng::seed_from_u64(seed);
    let baseline = rng.random_range(0.2..0.6);
    let pose = random_pose(&mut rng, 0.3, baseline);
    make_scene_with_pose(seed, pose, n, outlier_ratio, sigma, planar)
}

/// As [`make_scene`] with a given `T_21`.
pub fn make_scene_with_pose(
    seed: u64,
    pose: Isometry3<f64>,
    n: usize,
    outlier_ratio: f64,
    sigma: f64,
    planar: bool,
) -> Scene {
    let mut rng = StdRng::seed_from_u64(seed ^ 0x5eed);
    let cam = camera();
    let (mut points, mut u1, mut u2, mut is_inlier) = (vec![], vec![], vec![], vec![]);
    while u1.len() < n {
        let x = rng.random_range(-0.6..0.6);
        let y = rng.random_range(-0.45..0.45);
        let z = if planar {
            // The plane 0.2 X - 0.1 Y + Z = 4 along the ray (x, y, 1).
            4.0 / (1.0 + 0.2 * x - 0.1 * y)
        } else {
            rng.random_range(2.0..8.0)
        };
        let p = Point3::new(x * z, y * z, z);
        let Some(a) = cam.project(&p.coords) else {
            continue;
        };
        let Some(b) = cam.project(&(pose * p).coords) else {
            continue;
        };
        if !(0.0..640.0).contains(&b.x) || !(0.0..480.0).contains(&b.y) {
            continue;
        }
        let outlier = (u1.len() as f64) < outlier_ratio * n as f64;
        let noise = |rng: &mut StdRng| Vector2::new(gauss(rng), gauss(rng)) * sigma;
        let a = a + noise(&mut rng);
        let b = if outlier {
            Vector2::new(rng.random_range(0.0..640.0), rng.random_range(0.0..480.0))
        } else {
            b + noise(&mut rng)
        };
        points.push(p);
        u1.push(a);
        u2.push(b);
        is_inlier.push(!outlier);
    }
    Scene {
        pose,
        points,
        u1,
        u2,
        is_inlier,
    }
}
