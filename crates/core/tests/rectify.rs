//! Stereo rectification on synthetic rigs with exact geometry: rows agree, disparity is
//! `f b / Z`, an already rectified rig is left alone, invalid rigs are typed errors.

use nalgebra::{Isometry3, Point3, Rotation3, Translation3, UnitQuaternion, Vector2, Vector3};
use vofront_core::camera::{Camera, Distortion, Pinhole};
use vofront_core::rectify::{RectifyError, StereoRectification};
use vofront_core::rig::{Rig, RigError};
use vofront_core::undistort_map::UndistortMap;

const WIDTH: usize = 752;
const HEIGHT: usize = 480;

/// Two EuRoC-like radial-tangential cameras, the right one 11 cm along x (plus a little y, z)
/// and turned by a few degrees, both mounted on a body (IMU) frame with a non-trivial `T_BS`.
fn distorted_rig() -> (Rig, Isometry3<f64>) {
    let left = Camera::new(
        Pinhole::new(458.654, 457.296, 367.215, 248.375).unwrap(),
        Distortion::from_array([-0.2834, 0.0740, 0.00019, 1.76e-5, 0.0]),
    );
    let right = Camera::new(
        Pinhole::new(457.587, 456.134, 379.999, 255.238).unwrap(),
        Distortion::from_array([-0.2837, 0.0745, -0.0001, -3.6e-5, 0.0]),
    );
    let t_bs_left = Isometry3::new(
        Vector3::new(-0.0216, -0.0647, 0.0098),
        Vector3::new(0.02, -0.01, 1.55),
    );
    // The right camera's pose in the left camera: centre at (0.11, 0.004, -0.003) m, turned by
    // about 3 degrees.
    let t_lr = Isometry3::from_parts(
        Translation3::new(0.11, 0.004, -0.003),
        UnitQuaternion::from_scaled_axis(Vector3::new(0.02, -0.045, 0.015)),
    );
    let rig = Rig::stereo(left, t_bs_left, right, t_bs_left * t_lr).unwrap();
    (rig, t_lr.inverse())
}

#[test]
fn rectified_rows_agree_and_disparity_is_f_b_over_z() {
    let (rig, t_rl) = distorted_rig();
    let rect = StereoRectification::new(&rig, WIDTH, HEIGHT).expect("rectify");
    assert!((rect.baseline() - t_rl.translation.vector.norm()).abs() < 1e-12);
    assert!((rect.baseline() - rig.baseline().unwrap()).abs() < 1e-12);
    // Rectified cameras are parallel: R_right R_RL R_left^T = I.
    let residual =
        rect.rotation_right() * t_rl.rotation.to_rotation_matrix() * rect.rotation_left().inverse();
    let off = (residual.matrix() - nalgebra::Matrix3::identity()).norm();
    assert!(off < 1e-12, "{off}");
    let f = rect.pinhole().fx;
    let mut checked = 0;
    for iz in 0..6 {
        let z = 1.5 + 1.7 * iz as f64;
        for ix in -4..=4 {
            for iy in -3..=3 {
                let p_left = Vector3::new(0.25 * z * ix as f64 / 4.0, 0.2 * z * iy as f64 / 3.0, z);
                // A point, not a vector: `Isometry3 * Vector3` would skip the translation.
                let p_right = (t_rl * Point3::from(p_left)).coords;
                let (Some(raw_l), Some(raw_r)) = (
                    rig.left().project(&p_left),
                    rig.right().unwrap().project(&p_right),
                ) else {
                    continue;
                };
                let l = rect.rectify_left(&raw_l).expect("left rectifies");
                let r = rect.rectify_right(&raw_r).expect("right rectifies");
                assert!((l.y - r.y).abs() < 1e-6, "rows {} vs {}", l.y, r.y);
                let depth = (rect.rotation_left() * p_left).z;
                let disparity = l.x - r.x;
                let want = f * rect.baseline() / depth;
                assert!((disparity - want).abs() < 1e-6, "{disparity} vs {want}");
                assert!((rect.depth_of_disparity(disparity).unwrap() - depth).abs() < 1e-6 * depth);
                checked += 1;
            }
        }
    }
    assert!(checked > 300, "{checked} points checked");
}

#[test]
fn maps_invert_the_point_rectification_and_stay_inside_the_raw_images() {
    let (rig, _) = distorted_rig();
    let rect = StereoRectification::new(&rig, WIDTH, HEIGHT).expect("rectify");
    assert_eq!(rect.size(), (WIDTH, HEIGHT));
    for (map, forward) in [
        (
            rect.map_left(),
            StereoRectification::rectify_left as fn(&_, &_) -> _,
        ),
        (rect.map_right(), StereoRectification::rectify_right),
    ] {
        assert_eq!((map.width, map.height), (WIDTH, HEIGHT));
        for (i, (&sx, &sy)) in map.map_x.iter().zip(&map.map_y).enumerate() {
            // alpha = 0: every rectified pixel has a source inside the raw image (f32 slack).
            assert!(
                sx >= -1e-3 && sx <= (WIDTH - 1) as f32 + 1e-3,
                "x {sx} at {i}"
            );
            assert!(
                sy >= -1e-3 && sy <= (HEIGHT - 1) as f32 + 1e-3,
                "y {sy} at {i}"
            );
            if i % 97 == 0 {
                let back = forward(&rect, &Vector2::new(sx as f64, sy as f64)).expect("inside");
                let want = Vector2::new((i % WIDTH) as f64, (i / WIDTH) as f64);
                assert!((back - want).norm() < 2e-3, "{back:?} vs {want:?}");
            }
        }
    }
    // The framing is tight: some rectified border pixel reaches a raw image edge.
    let map = rect.map_left();
    let reach = map
        .map_x
        .iter()
        .zip(&map.map_y)
        .map(|(&x, &y)| {
            x.min(y)
                .min((WIDTH - 1) as f32 - x)
                .min((HEIGHT - 1) as f32 - y)
        })
        .fold(f32::INFINITY, f32::min);
    let reach_right = rect
        .map_right()
        .map_x
        .iter()
        .zip(&rect.map_right().map_y)
        .map(|(&x, &y)| {
            x.min(y)
                .min((WIDTH - 1) as f32 - x)
                .min((HEIGHT - 1) as f32 - y)
        })
        .fold(f32::INFINITY, f32::min);
    assert!(reach.min(reach_right) < 0.01, "{reach} {reach_right}");
}

#[test]
fn an_already_rectified_rig_keeps_its_pinhole_and_identity_rotations() {
    // KITTI 06: one pinhole, the right camera 0.537 m to the right, no distortion.
    let pinhole = Pinhole::new(707.0912, 707.0912, 601.8873, 183.1104).unwrap();
    let cam = Camera::pinhole(pinhole);
    let right_in_left = Isometry3::translation(0.537_150_588, 0.0, 0.0);
    let rig = Rig::stereo(cam, Isometry3::identity(), cam, right_in_left).unwrap();
    let rect = StereoRectification::new(&rig, 1226, 370).expect("rectify");
    assert_eq!(*rect.rotation_left(), Rotation3::identity());
    assert_eq!(*rect.rotation_right(), Rotation3::identity());
    let p = rect.pinhole();
    for (got, want) in [
        (p.fx, pinhole.fx),
        (p.fy, pinhole.fy),
        (p.cx, pinhole.cx),
        (p.cy, pinhole.cy),
    ] {
        assert!((got - want).abs() < 1e-9, "{got} vs {want}");
    }
    assert!((rect.baseline() - 0.537_150_588).abs() < 1e-15);
    // The maps are the identity.
    let map = rect.map_right();
    for (i, (&x, &y)) in map.map_x.iter().zip(&map.map_y).enumerate().step_by(101) {
        assert!((x - (i % 1226) as f32).abs() < 1e-3 && (y - (i / 1226) as f32).abs() < 1e-3);
    }
}

#[test]
fn rotated_map_with_the_identity_is_the_undistortion_map() {
    let (rig, _) = distorted_rig();
    let cam = rig.left();
    let plain = UndistortMap::new(cam, &cam.pinhole, 64, 48).unwrap();
    let rotated = UndistortMap::rotated(cam, &Rotation3::identity(), &cam.pinhole, 64, 48).unwrap();
    assert_eq!(plain, rotated);
    // A half turn puts every ray behind the camera: no source anywhere.
    let behind = Rotation3::from_axis_angle(&Vector3::y_axis(), std::f64::consts::PI);
    let away = UndistortMap::rotated(cam, &behind, &cam.pinhole, 8, 6).unwrap();
    assert!(away.map_x.iter().chain(&away.map_y).all(|v| v.is_nan()));
}

#[test]
fn invalid_rigs_are_typed_errors() {
    let cam = Camera::pinhole(Pinhole::new(500.0, 500.0, 320.0, 240.0).unwrap());
    let i = Isometry3::identity();
    assert!(matches!(
        Rig::stereo(cam, i, cam, i),
        Err(RigError::ZeroBaseline { .. })
    ));
    let mono = Rig::mono(cam).unwrap();
    assert_eq!(
        StereoRectification::new(&mono, 640, 480),
        Err(RectifyError::Mono)
    );
    let stereo =
        |x: f64, y: f64, z: f64| Rig::stereo(cam, i, cam, Isometry3::translation(x, y, z)).unwrap();
    assert!(matches!(
        StereoRectification::new(&stereo(0.01, 0.1, 0.0), 640, 480),
        Err(RectifyError::NotSideBySide { .. })
    ));
    assert!(matches!(
        StereoRectification::new(&stereo(0.0, 0.0, 0.1), 640, 480),
        Err(RectifyError::NotSideBySide { .. })
    ));
    assert_eq!(
        StereoRectification::new(&stereo(-0.1, 0.0, 0.0), 640, 480),
        Err(RectifyError::CamerasSwapped)
    );
    assert_eq!(
        StereoRectification::new(&stereo(0.1, 0.0, 0.0), 1, 480),
        Err(RectifyError::ImageTooSmall {
            width: 1,
            height: 480
        })
    );
    // Cameras turned 100 degrees apart see nothing in common.
    let turned = Isometry3::from_parts(
        Translation3::new(0.1, 0.0, 0.0),
        UnitQuaternion::from_scaled_axis(Vector3::new(0.0, 1.75, 0.0)),
    );
    let rig = Rig::stereo(cam, i, cam, turned).unwrap();
    assert!(StereoRectification::new(&rig, 640, 480).is_err());
}
