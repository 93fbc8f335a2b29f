//! Two views whose first is a rectified stereo pair (`two-view --right1`): on the rendered
//! stereo drive and room, the metric `feature_stereo` pose recovers the exact `T_21` in metres,
//! and so does the direct SE(3) pose on frame 1's stereo depth in the room (on the drive, 2 m
//! ahead, it may fail but is never `ok` and wrong); the metric pose agrees with the epipolar
//! one, and is flagged `inconsistent` against an epipolar pose it contradicts (the direct pose
//! is compared in the same way); bad stereo
//! input is a typed error in its own entry, never a pose.

use nalgebra::{Isometry3, UnitQuaternion, Vector3};
use vofront::fixtures::image2d::to_gray8;
use vofront::fixtures::stereo::StereoSequence;
use vofront::geometry::RelativePose;
use vofront::two_view::stereo::{
    check_against_epipolar, epipolar_disagreement_sigmas, StereoFirst, StereoPose,
    MAX_DISAGREEMENT_SIGMAS,
};
use vofront::two_view::{estimate, Inputs, Method, Outcome};
use vofront_core::{Camera, Distortion, Lens};
use vofront_robust::{Reason, Verdict};

/// The estimates of frames `(0, gap)` of `seq`, frame 0 with its right image.
fn pair(seq: &StereoSequence, gap: usize, camera: Camera, baseline: f64) -> Outcome {
    let (first, second) = (seq.render(0), seq.render(gap));
    estimate(&Inputs {
        img1: to_gray8(&first.left.image),
        img2: to_gray8(&second.left.image),
        depth1: None,
        camera,
        method: Method::All,
        features: 2000,
        stereo: Some(StereoFirst {
            right1: to_gray8(&first.right.image),
            baseline,
        }),
    })
}

/// Rotation (degrees) and translation (metres) errors of `estimate` against `truth`.
fn errors(estimate: &Isometry3<f64>, truth: &Isometry3<f64>) -> (f64, f64) {
    let d = estimate.inverse() * truth;
    (
        d.rotation.angle().to_degrees(),
        (estimate.translation.vector - truth.translation.vector).norm(),
    )
}

fn check_metric(seq: &StereoSequence, gap: usize, direct_required: bool) {
    let truth = seq.poses_wc[gap].inverse() * seq.poses_wc[0];
    let motion = truth.translation.vector.norm();
    let outcome = pair(seq, gap, seq.camera, seq.baseline);
    let stereo = outcome
        .feature_stereo
        .as_ref()
        .expect("ran")
        .as_ref()
        .expect("stereo pose");
    let (rot, trans) = errors(&stereo.pnp.pose, &truth);
    assert!(stereo.pnp.quality.is_ok(), "{:?}", stereo.pnp.quality);
    assert!(rot < 0.1, "stereo rotation error {rot} deg");
    assert!(
        trans < 0.02 * motion.max(0.1),
        "stereo translation error {trans} m of {motion} m"
    );
    match outcome
        .se3
        .as_ref()
        .expect("direct ran on the stereo depth")
    {
        Ok((se3, _)) if se3.quality.is_ok() => {
            let (rot, trans) = errors(&se3.pose, &truth);
            assert!(rot < 0.2, "direct rotation error {rot} deg");
            assert!(
                trans < 0.05 * motion.max(0.1),
                "direct translation error {trans} m of {motion} m"
            );
        }
        // Beyond the direct basin from the identity (metres of forward motion): an error or
        // a verdict that is not ok, never a confident wrong pose.
        other => assert!(!direct_required, "direct: {:?}", other.as_ref().err()),
    }
    assert_eq!(outcome.recommend().estimate, Some("feature_stereo"));
    // Compared with the epipolar pose when that is ok, and in agreement with it.
    let epipolar = outcome
        .feature
        .as_ref()
        .expect("ran")
        .as_ref()
        .expect("epipolar pose");
    if epipolar.estimate.quality.is_ok() {
        let agreement = stereo.epipolar_disagreement_sigmas.expect("compared");
        assert!(agreement < MAX_DISAGREEMENT_SIGMAS, "{agreement} sigmas");
    } else {
        assert_eq!(stereo.epipolar_disagreement_sigmas, None);
    }
}

/// The stereo and the epipolar estimates of frames 0 and 2 of the rendered stereo street.
fn street_stereo_and_epipolar() -> (StereoPose, RelativePose) {
    let seq = StereoSequence::driving(3, 3);
    let outcome = pair(&seq, 2, seq.camera, seq.baseline);
    let stereo = outcome.feature_stereo.expect("ran").expect("stereo pose");
    let epipolar = outcome
        .feature
        .expect("ran")
        .expect("epipolar pose")
        .estimate;
    (stereo, epipolar)
}

/// An epipolar pose turned by 1 degree about the vertical (the yaw a far-point PnP can trade
/// for sideways motion), or with its direction turned by 20 degrees, contradicts the metric
/// pose: the metric pose becomes `unreliable` (`inconsistent`), and the recommendation moves
/// to the epipolar estimate. An epipolar estimate that is not `ok` is not compared.
#[test]
fn a_metric_pose_that_contradicts_the_epipolar_one_is_inconsistent() {
    let (stereo, epipolar) = street_stereo_and_epipolar();
    assert!(epipolar.quality.is_ok());
    let yaw = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 1f64.to_radians());
    let mut turned = epipolar.clone();
    turned.pose.rotation = yaw * turned.pose.rotation;
    let mut swerved = epipolar.clone();
    swerved.pose.translation.vector =
        UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 20f64.to_radians())
            * swerved.pose.translation.vector;
    for contradicting in [&turned, &swerved] {
        let mut checked = stereo.clone();
        check_against_epipolar(&mut checked, contradicting);
        assert!(checked.epipolar_disagreement_sigmas.expect("compared") > MAX_DISAGREEMENT_SIGMAS);
        assert_eq!(checked.pnp.quality.verdict, Verdict::Unreliable);
        assert!(checked.pnp.quality.reasons.contains(&Reason::Inconsistent));
    }
    let mut unjudged = turned.clone();
    unjudged.quality.flag(Reason::LowParallax);
    let mut checked = stereo.clone();
    checked.epipolar_disagreement_sigmas = None;
    check_against_epipolar(&mut checked, &unjudged);
    assert_eq!(checked.epipolar_disagreement_sigmas, None);
    assert!(checked.pnp.quality.is_ok());
}

/// Rotation and direction are judged together: an epipolar pose turned in yaw and in its
/// direction of travel by amounts that each alone stay under [`MAX_DISAGREEMENT_SIGMAS`]
/// (8.5 sigmas each, measured from the 1-degree and 20-degree turns) puts the metric pose
/// beyond it (a far-point PnP that trades yaw for sideways motion moves both).
#[test]
fn rotation_and_direction_disagreements_add_up() {
    let (stereo, epipolar) = street_stereo_and_epipolar();
    let sigmas = |yaw_deg: f64, swerve_deg: f64| {
        let mut e = epipolar.clone();
        let about_y =
            |deg: f64| UnitQuaternion::from_axis_angle(&Vector3::y_axis(), deg.to_radians());
        e.pose.rotation = about_y(yaw_deg) * e.pose.rotation;
        e.pose.translation.vector = about_y(swerve_deg) * e.pose.translation.vector;
        epipolar_disagreement_sigmas(
            &stereo.pnp.pose,
            &stereo.pnp.quality,
            stereo.pnp.covariance.as_ref(),
            &e,
        )
        .expect("compared")
    };
    let yaw = 8.5 / sigmas(1.0, 0.0);
    let swerve = 20.0 * 8.5 / sigmas(0.0, 20.0);
    let (turned, swerved, both) = (sigmas(yaw, 0.0), sigmas(0.0, swerve), sigmas(yaw, swerve));
    assert!(turned < MAX_DISAGREEMENT_SIGMAS, "{turned}");
    assert!(swerved < MAX_DISAGREEMENT_SIGMAS, "{swerved}");
    assert!(both > MAX_DISAGREEMENT_SIGMAS, "{both}");
    assert!(
        (both - turned.hypot(swerved)).abs() < 1.5,
        "{both} {turned} {swerved}"
    );
}

/// The direct SE(3) pose on frame 1's stereo depth answers to the epipolar pose in the same
/// way: in the room it agrees with it (and stays `ok` in the outcome), and an epipolar pose
/// turned by 1 degree of yaw or 20 degrees of direction puts it beyond
/// [`MAX_DISAGREEMENT_SIGMAS`], which `estimate` flags `inconsistent`.
#[test]
fn the_direct_metric_pose_is_compared_with_the_epipolar_one() {
    let seq = StereoSequence::room(5, 6);
    let outcome = pair(&seq, 5, seq.camera, seq.baseline);
    let (se3, _) = outcome.se3.expect("ran").expect("direct pose");
    let epipolar = outcome
        .feature
        .expect("ran")
        .expect("epipolar pose")
        .estimate;
    assert!(
        epipolar.quality.is_ok() && se3.quality.is_ok(),
        "{:?} {:?}",
        epipolar.quality,
        se3.quality
    );
    let disagreement = |e: &RelativePose| {
        epipolar_disagreement_sigmas(&se3.pose, &se3.quality, se3.covariance.as_ref(), e)
            .expect("compared")
    };
    assert!(disagreement(&epipolar) < MAX_DISAGREEMENT_SIGMAS);
    let mut turned = epipolar.clone();
    turned.pose.rotation = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 1f64.to_radians())
        * turned.pose.rotation;
    let mut swerved = epipolar.clone();
    swerved.pose.translation.vector =
        UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 20f64.to_radians())
            * swerved.pose.translation.vector;
    for contradicting in [&turned, &swerved] {
        assert!(disagreement(contradicting) > MAX_DISAGREEMENT_SIGMAS);
    }
}

#[test]
fn stereo_first_frame_gives_the_metric_pose_on_the_drive() {
    check_metric(&StereoSequence::driving(3, 3), 2, false);
}

#[test]
fn stereo_first_frame_gives_the_metric_pose_in_the_room() {
    check_metric(&StereoSequence::room(5, 4), 3, true);
}

#[test]
fn a_distorted_camera_or_a_wrong_size_is_a_typed_error() {
    let seq = StereoSequence::room(5, 2);
    let mut distorted = seq.camera;
    distorted.distortion = Lens::RadialTangential(Distortion {
        k1: 0.1,
        ..Distortion::default()
    });
    let outcome = pair(&seq, 1, distorted, seq.baseline);
    let err = outcome.feature_stereo.expect("ran").expect_err("refused");
    assert!(err.to_string().contains("rectified"), "{err}");
    assert!(outcome.se3.expect("ran").is_err());

    let first = seq.render(0);
    let small = to_gray8(&seq.render(1).left.image);
    let cropped = vofront::image::Image::new(8, 8, small.data()[..64].to_vec()).unwrap();
    let outcome = estimate(&Inputs {
        img1: to_gray8(&first.left.image),
        img2: cropped,
        depth1: None,
        camera: seq.camera,
        method: Method::Feature,
        features: 500,
        stereo: Some(StereoFirst {
            right1: to_gray8(&first.right.image),
            baseline: seq.baseline,
        }),
    });
    assert!(outcome.feature_stereo.expect("ran").is_err());
    assert!(outcome.se3.is_none());
}
