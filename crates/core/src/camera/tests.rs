//! Tests of the camera models.

use super::*;
use proptest::prelude::*;

const TUM_FR1: [f64; 5] = [0.2624, -0.9531, -0.0054, 0.0026, 1.1633];

#[test]
fn zero_or_nan_focal_length_is_rejected() {
    assert!(matches!(
        Pinhole::new(0.0, 500.0, 320.0, 240.0),
        Err(CameraError::BadFocalLength { .. })
    ));
    assert!(matches!(
        Pinhole::new(f64::NAN, 500.0, 320.0, 240.0),
        Err(CameraError::BadFocalLength { .. })
    ));
    assert_eq!(
        Pinhole::new(500.0, 500.0, f64::INFINITY, 240.0),
        Err(CameraError::NotFinite)
    );
}

/// A Kannala-Brandt lens with TUM-VI-sized coefficients and a stronger one.
fn fisheyes() -> [KannalaBrandt; 2] {
    [
        KannalaBrandt::new([0.0034, 0.0007, -0.0021, 0.0002]).unwrap(),
        KannalaBrandt::new([-0.05, 0.01, -0.002, 0.0003]).unwrap(),
    ]
}

/// Every model, each with the largest angle to the axis (radians) its tests use.
fn lenses() -> Vec<(Lens, f64)> {
    let mut all = vec![
        (Lens::default(), 1.3),
        (Distortion::from_array(TUM_FR1).into(), 0.4),
    ];
    all.extend(fisheyes().map(|k| (Lens::from(k), 1.45)));
    all
}

/// The camera-frame point at `depth` metres along the ray `theta` off the axis at
/// azimuth `phi`.
fn ray_point(theta: f64, phi: f64, depth: f64) -> Vector3<f64> {
    depth
        * Vector3::new(
            theta.sin() * phi.cos(),
            theta.sin() * phi.sin(),
            theta.cos(),
        )
}

#[test]
fn equidistant_lens_maps_angle_to_radius() {
    // With every k zero, theta_d = theta: the pixel radius is f theta.
    let cam = Camera::new(
        Pinhole::new(300.0, 300.0, 320.0, 240.0).unwrap(),
        KannalaBrandt::new([0.0; 4]).unwrap(),
    );
    let theta = 1.2f64;
    let px = cam.project(&ray_point(theta, 0.0, 2.0)).unwrap();
    assert!((px.x - 320.0 - 300.0 * theta).abs() < 1e-9 && (px.y - 240.0).abs() < 1e-9);
    assert!(!cam.distortion.is_identity());
    assert_eq!(cam.distortion.model_name(), "equidistant");
}

proptest! {
    #[test]
    fn undistort_inverts_distort(x in -0.6f64..0.6, y in -0.45f64..0.45) {
        let d = Distortion::from_array(TUM_FR1);
        let xn = Vector2::new(x, y);
        let back = d.undistort(&d.distort(&xn)).unwrap();
        prop_assert!((back - xn).norm() < 1e-9);
    }

    #[test]
    fn distort_jacobian_matches_finite_differences(x in -0.6f64..0.6, y in -0.45f64..0.45) {
        let d = Distortion::from_array(TUM_FR1);
        let xn = Vector2::new(x, y);
        let j = d.distort_jacobian(&xn);
        let h = 1e-7;
        for k in 0..2 {
            let mut e = Vector2::zeros();
            e[k] = h;
            let numeric = (d.distort(&(xn + e)) - d.distort(&(xn - e))) / (2.0 * h);
            prop_assert!((numeric - j.column(k)).norm() < 1e-6);
        }
    }

    #[test]
    fn pixel_and_point_round_trip(u in 0.0f64..640.0, v in 0.0f64..480.0, z in 0.2f64..20.0) {
        let k = Pinhole::new(520.0, 515.0, 320.0, 240.0).unwrap();
        let px = Vector2::new(u, v);
        let p = k.back_project(&px, z);
        prop_assert!((k.project(&p).unwrap() - px).norm() < 1e-9);
        let (pixel, j) = Camera::pinhole(k).project_with_jacobian(&p).unwrap();
        prop_assert!((pixel - px).norm() < 1e-9);
        let h = 1e-6;
        for c in 0..3 {
            let mut e = Vector3::zeros();
            e[c] = h;
            let numeric = (k.project(&(p + e)).unwrap() - k.project(&(p - e)).unwrap()) / (2.0 * h);
            prop_assert!((numeric - j.column(c)).norm() < 1e-5);
        }
    }

    #[test]
    fn every_model_projects_and_unprojects(theta_frac in 0.0f64..1.0, phi in -3.2f64..3.2, depth in 0.2f64..30.0) {
        let k = Pinhole::new(380.0, 375.0, 320.0, 240.0).unwrap();
        for (lens, max_theta) in lenses() {
            let cam = Camera::new(k, lens);
            let p = ray_point(theta_frac * max_theta, phi, depth);
            let px = cam.project(&p).unwrap();
            let ray = cam.bearing(&px).unwrap();
            prop_assert!((ray.into_inner() - p.normalize()).norm() < 1e-9, "{lens:?}");
        }
    }

    #[test]
    fn every_model_has_exact_jacobians(theta_frac in 0.0f64..1.0, phi in -3.2f64..3.2, depth in 0.5f64..10.0) {
        let k = Pinhole::new(380.0, 375.0, 320.0, 240.0).unwrap();
        for (lens, max_theta) in lenses() {
            let cam = Camera::new(k, lens);
            let p = ray_point(theta_frac * max_theta, phi, depth);
            let xn = Vector2::new(p.x / p.z, p.y / p.z);
            let jd = lens.distort_jacobian(&xn);
            let h = 1e-7;
            for c in 0..2 {
                let mut e = Vector2::zeros();
                e[c] = h;
                let numeric = (lens.distort(&(xn + e)) - lens.distort(&(xn - e))) / (2.0 * h);
                // Relative to the Jacobian's size: normalized coordinates reach tan(83 deg).
                prop_assert!((numeric - jd.column(c)).norm() < 1e-6 * (1.0 + jd.norm()), "{lens:?}");
            }
            let (pixel, jp) = cam.project_with_jacobian(&p).unwrap();
            prop_assert!((pixel - cam.project(&p).unwrap()).norm() < 1e-9, "{lens:?}");
            prop_assert_eq!(cam.project_jacobian(&p), Some(jp));
            let h = 1e-6 * depth;
            for c in 0..3 {
                let mut e = Vector3::zeros();
                e[c] = h;
                let numeric = (cam.project(&(p + e)).unwrap() - cam.project(&(p - e)).unwrap()) / (2.0 * h);
                prop_assert!((numeric - jp.column(c)).norm() < 1e-5 * (1.0 + jp.norm()), "{lens:?}");
            }
        }
    }

    #[test]
    fn no_jacobian_behind_the_camera_or_outside_the_lens(phi in -3.2f64..3.2, depth in 0.5f64..10.0) {
        let k = Pinhole::new(380.0, 375.0, 320.0, 240.0).unwrap();
        // theta_d' = 1 - 0.9 theta^2: the range ends at 1.054 rad, in front of the camera.
        let lens = KannalaBrandt::new([-0.3, 0.0, 0.0, 0.0]).unwrap();
        let cam = Camera::new(k, lens);
        let inside = ray_point(lens.theta_max() - 0.01, phi, depth);
        prop_assert!(cam.project_with_jacobian(&inside).is_some());
        let past = ray_point(lens.theta_max() + 0.01, phi, depth);
        prop_assert!(past.z > 0.0 && cam.project_with_jacobian(&past).is_none());
        prop_assert!(cam.project_with_jacobian(&(-inside)).is_none());
    }

    #[test]
    fn fisheye_pixels_outside_the_lens_have_no_ray(scale in 1.0001f64..3.0, phi in -3.2f64..3.2) {
        for lens in fisheyes() {
            let edge = lens.theta_d(lens.theta_max()) * scale;
            let xd = Vector2::new(edge * phi.cos(), edge * phi.sin());
            prop_assert_eq!(lens.undistort(&xd), None);
        }
    }
}
