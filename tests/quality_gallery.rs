//! A gallery of failure scenes, each with the verdicts its estimates must get, and good
//! scenes that must stay `ok`. Rule behind every case: an `ok` estimate is accurate, and
//! input that carries no motion information never yields an `ok` estimate.

use nalgebra::{Isometry3, Matrix3, Translation3, UnitQuaternion, Vector3};
use vofront::fixtures::image2d::{
    add_gaussian_noise, textured_image, to_gray8, translation, warped_textured_image,
};
use vofront::fixtures::scene::{default_camera, pose_wc, Scene};
use vofront::geometry::Camera;
use vofront::image::Image;
use vofront::pipeline::TwoViewEstimator;
use vofront::robust::{Reason, Verdict};
use vofront::two_view::{estimate, Inputs, Method, Outcome, Status};

/// Rotation error an `ok` feature pose may have on these noise-free renderings, degrees.
const OK_ROTATION_DEG: f64 = 0.5;

fn run(img1: Image<u8>, img2: Image<u8>, depth1: Option<Image<f32>>) -> Outcome {
    estimate(&Inputs {
        img1,
        img2,
        depth1,
        camera: default_camera(),
        method: Method::All,
        features: 1000,
        stereo: None,
    })
}

/// Verdict of the feature estimate, `None` when it is an error.
fn feature_verdict(o: &Outcome) -> Option<Verdict> {
    match &o.feature {
        Some(Ok(f)) => Some(f.estimate.quality.verdict),
        _ => None,
    }
}

fn translation_verdict(o: &Outcome) -> Option<Verdict> {
    match &o.translation {
        Some(Ok((d, _))) => Some(d.quality.verdict),
        _ => None,
    }
}

fn print(name: &str, o: &Outcome) {
    println!(
        "{name}: {}",
        serde_json::to_string(&o.report()).unwrap_or_default()
    );
}

/// Two views of the box room, the first with depth.
fn room_pair(t_w2: Isometry3<f64>) -> (Image<u8>, Image<u8>, Image<f32>, Isometry3<f64>) {
    let room = Scene::box_room(3);
    let cam = default_camera();
    let t_w1 = pose_wc([0.0; 3], 0.0, 0.0, 0.0);
    let v1 = room.render(&cam, 640, 480, &t_w1);
    let v2 = room.render(&cam, 640, 480, &t_w2);
    (
        to_gray8(&v1.image),
        to_gray8(&v2.image),
        v1.depth,
        t_w2.inverse() * t_w1,
    )
}

fn rotation_error_deg(o: &Outcome, truth: &Isometry3<f64>) -> f64 {
    match &o.feature {
        Some(Ok(f)) => f.estimate.rotation().angle_to(&truth.rotation).to_degrees(),
        _ => f64::INFINITY,
    }
}

#[test]
fn good_room_pair_is_ok_and_recommends_the_metric_pose() {
    let (a, b, depth, truth) = room_pair(pose_wc([0.15, -0.03, 0.06], -0.06, 0.02, 0.01));
    let o = run(a, b, Some(depth));
    print("room", &o);
    assert_eq!(feature_verdict(&o), Some(Verdict::Ok));
    assert!(rotation_error_deg(&o, &truth) < OK_ROTATION_DEG);
    assert!(
        matches!(&o.se3, Some(Ok((s, _))) if s.quality.verdict == Verdict::Ok),
        "direct SE(3) must be ok"
    );
    assert_eq!(o.status(), Status::Ok);
    assert_eq!(o.recommend().estimate, Some("direct_se3"));
    let json = serde_json::to_value(o.report()).expect("serialises");
    assert_eq!(json["feature"]["quality"]["verdict"], "ok");
    assert_eq!(json["recommended"]["estimate"], "direct_se3");
    assert!(json["direct_se3"]["quality"]["rotation_sigma_deg"]
        .as_f64()
        .is_some());
}

#[test]
fn unrelated_textures_are_never_ok() {
    let o = run(
        to_gray8(&textured_image(640, 480, 1)),
        to_gray8(&textured_image(640, 480, 2)),
        None,
    );
    print("unrelated", &o);
    assert_ne!(feature_verdict(&o), Some(Verdict::Ok));
    assert_ne!(feature_verdict(&o), Some(Verdict::Unreliable));
    assert_eq!(translation_verdict(&o), Some(Verdict::Failed));
    assert_ne!(o.status(), Status::Ok);
    assert_eq!(o.recommend().estimate, None);
}

#[test]
fn independent_noise_is_never_ok() {
    let flat = Image::filled(640, 480, 128.0f32);
    let o = run(
        to_gray8(&add_gaussian_noise(&flat, 40.0, 1)),
        to_gray8(&add_gaussian_noise(&flat, 40.0, 2)),
        None,
    );
    print("noise", &o);
    assert_ne!(feature_verdict(&o), Some(Verdict::Ok));
    assert_ne!(translation_verdict(&o), Some(Verdict::Ok));
    assert_ne!(o.status(), Status::Ok);
}

#[test]
fn blank_images_give_no_estimate() {
    let blank = Image::filled(640, 480, 90u8);
    let o = run(blank.clone(), blank, None);
    print("blank", &o);
    assert!(!matches!(o.feature, Some(Ok(_))));
    assert_ne!(translation_verdict(&o), Some(Verdict::Ok));
    assert_ne!(o.status(), Status::Ok);
}

#[test]
fn identical_images_give_an_unreliable_motion_and_an_ok_zero_shift() {
    let img = to_gray8(&textured_image(640, 480, 4));
    let o = run(img.clone(), img, None);
    print("identical", &o);
    // No translation can be seen: the pose is a pure (identity) rotation, not `ok`.
    assert_eq!(feature_verdict(&o), Some(Verdict::Unreliable));
    match &o.feature {
        Some(Ok(f)) => {
            assert!(f.estimate.quality.reasons.contains(&Reason::PureRotation));
            assert!(f.estimate.rotation().angle().to_degrees() < 0.05);
        }
        _ => unreachable!("verdict checked above"),
    }
    // The 2D shift of identical images is exactly known: zero.
    assert_eq!(translation_verdict(&o), Some(Verdict::Ok));
    let d = &o
        .translation
        .as_ref()
        .and_then(|r| r.as_ref().ok())
        .map(|t| t.0.d);
    assert!(d.is_some_and(|d| d.norm() < 0.01), "{d:?}");
}

#[test]
fn pure_rotation_is_unreliable_with_an_accurate_rotation() {
    let (a, b, _, truth) = room_pair(pose_wc([0.0; 3], -0.05, 0.03, 0.0));
    let o = run(a, b, None);
    print("rotation", &o);
    assert_eq!(feature_verdict(&o), Some(Verdict::Unreliable));
    assert!(rotation_error_deg(&o, &truth) < OK_ROTATION_DEG);
}

/// Plane `Z = 3` seen from camera 1, camera 2 rotated and moved,
/// `x2 ~ K (R + t n^T / d) K^-1 x1`: the motion and the two textured images.
fn plane_pair() -> (Isometry3<f64>, Image<u8>, Image<u8>) {
    let cam: Camera = default_camera();
    let k = cam.pinhole.matrix();
    let truth = Isometry3::from_parts(
        Translation3::new(0.25, 0.05, 0.05),
        UnitQuaternion::from_scaled_axis(Vector3::new(0.02, -0.04, 0.01)),
    );
    let n_over_d = Vector3::new(0.0, 0.0, 1.0 / 3.0);
    let h: Matrix3<f64> = k
        * (truth.rotation.to_rotation_matrix().into_inner()
            + truth.translation.vector * n_over_d.transpose())
        * k.try_inverse().expect("intrinsics are invertible");
    (
        truth,
        to_gray8(&textured_image(640, 480, 5)),
        to_gray8(&warped_textured_image(640, 480, 5, &h)),
    )
}

#[test]
fn a_plane_is_never_confidently_wrong() {
    let (truth, img1, img2) = plane_pair();
    let o = run(img1, img2, None);
    print("plane", &o);
    let verdict = feature_verdict(&o);
    assert!(verdict.is_some(), "a textured plane has a pose");
    if verdict == Some(Verdict::Ok) {
        assert!(rotation_error_deg(&o, &truth) < OK_ROTATION_DEG);
    }
}

/// A plane's points admit two motions (the homography's twins), and which one the search
/// lands on depends on its random draws: whichever it is, the wrong twin is never `ok`.
/// (Local optimisation on at most 512 inliers, before the refined motions were also compared
/// by how many points each puts in front of both cameras, made 3 of these 40 seeds `ok` at
/// 4.9 degrees off.)
#[test]
fn a_plane_is_never_confidently_wrong_whatever_the_seed() {
    let (truth, img1, img2) = plane_pair();
    let mut estimator = TwoViewEstimator::default();
    estimator.orb.n_features = 1000;
    for seed in 0..40 {
        estimator.geometry.ransac.seed = seed;
        let fit = estimator
            .relative_pose(&img1, &img2, &default_camera())
            .expect("a textured plane has a pose");
        let error = fit
            .estimate
            .rotation()
            .angle_to(&truth.rotation)
            .to_degrees();
        if fit.estimate.quality.verdict == Verdict::Ok {
            assert!(
                error < OK_ROTATION_DEG,
                "seed {seed}: ok at {error} deg off ({:?})",
                fit.estimate.model
            );
        }
    }
}

#[test]
fn a_repeated_pattern_is_never_confidently_wrong() {
    // Stripes repeating every 16 pixels, shifted by 5: every match has twins.
    let stripes = |shift: f64| {
        let data = (0..640 * 480).map(|i| {
            let (x, y) = (i % 640, i / 640);
            let v = 128.0
                + 100.0 * ((x as f64 + shift) * std::f64::consts::TAU / 16.0).sin()
                + 20.0 * ((y as f64) * std::f64::consts::TAU / 64.0).sin();
            v.clamp(0.0, 255.0) as u8
        });
        Image::new(640, 480, data.collect()).expect("640 * 480 values")
    };
    let o = run(stripes(0.0), stripes(5.0), None);
    print("stripes", &o);
    assert_ne!(feature_verdict(&o), Some(Verdict::Ok));
}

#[test]
fn views_without_overlap_are_never_ok() {
    // Two disjoint windows of one texture: same statistics, no common content.
    let big = textured_image(1280, 480, 6);
    let window = |x0: usize| {
        let rows = (0..480).flat_map(|y| big.row(y)[x0..x0 + 640].iter().copied());
        Image::new(640, 480, rows.collect()).expect("640 * 480 values")
    };
    let (left, right) = (window(0), window(640));
    let o = run(to_gray8(&left), to_gray8(&right), None);
    print("no overlap", &o);
    assert_ne!(feature_verdict(&o), Some(Verdict::Ok));
    assert_ne!(translation_verdict(&o), Some(Verdict::Ok));
    assert_ne!(o.status(), Status::Ok);
}

#[test]
fn a_shifted_texture_gives_an_ok_shift() {
    let o = run(
        to_gray8(&textured_image(640, 480, 7)),
        to_gray8(&warped_textured_image(640, 480, 7, &translation(3.2, -1.4))),
        None,
    );
    print("shift", &o);
    assert_eq!(translation_verdict(&o), Some(Verdict::Ok));
}
