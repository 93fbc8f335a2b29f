//! The photometric bundle recovers perturbed poses, brightness and inverse depths of a
//! rendered textured plane (exact ground truth), flags points that match nothing, and rejects
//! bad input with typed errors.

use nalgebra::{Isometry3, Vector2, Vector3, Vector6};
use vofront_core::lie::{retract_left, rotation_angle_deg};
use vofront_image::Image;

use super::*;
use crate::mono::select::{select_points, SelectConfig};
use crate::mono::tests::{pinhole, pose, render, DEPTH};

/// True inverse depth of host pixel `x` of a camera at `t_cw` (world = the plane's reference
/// camera): its ray cut with the plane `Z = DEPTH`, in the camera's frame.
fn true_rho(t_cw: &Isometry3<f64>, x: Vector2<f32>) -> f64 {
    let k = pinhole();
    let t_wc = t_cw.inverse();
    let c = t_wc.translation.vector;
    let bearing = Vector3::new(
        (f64::from(x.x) - k.cx) / k.fx,
        (f64::from(x.y) - k.cy) / k.fy,
        1.0,
    );
    let d = t_wc.rotation * bearing;
    let world = c + d * ((DEPTH - c.z) / d.z);
    1.0 / (t_cw * nalgebra::Point3::from(world)).z
}

/// Four frames of the plane (poses 0, 2, 4, 6 steps from the reference), the last one seen
/// with gain 1.1 and offset 8; the points selected in frame 2 with their true inverse depths.
struct Window {
    images: Vec<Image<f32>>,
    truth: Vec<FrameState>,
    points: Vec<BundlePoint>,
}

fn window() -> Window {
    let truth: Vec<FrameState> = [0, 2, 4, 6]
        .iter()
        .enumerate()
        .map(|(i, &s)| FrameState {
            t_cw: pose(s),
            a: if i == 3 { 1.1f64.ln() } else { 0.0 },
            b: if i == 3 { 8.0 } else { 0.0 },
        })
        .collect();
    let images: Vec<Image<f32>> = truth
        .iter()
        .map(|f| {
            render(&f.t_cw)
                .blur()
                .map(|v| (f.a.exp() as f32) * *v + f.b as f32)
        })
        .collect();
    let host = 2;
    let points = select_points(&images[host], &SelectConfig::default())
        .unwrap()
        .iter()
        .map(|c| BundlePoint {
            host,
            pixel: c.pixel,
            rho: true_rho(&truth[host].t_cw, c.pixel),
        })
        .collect();
    Window {
        images,
        truth,
        points,
    }
}

fn frames<'a>(images: &'a [Image<f32>], states: &[FrameState]) -> Vec<BundleFrame<'a>> {
    images
        .iter()
        .zip(states)
        .map(|(image, &state)| BundleFrame { image, state })
        .collect()
}

#[test]
fn perturbed_poses_brightness_and_depths_return_to_the_truth() {
    let w = window();
    assert!(w.points.len() > 60, "{}", w.points.len());
    let mut start = w.truth.clone();
    // The free frames (2: the host, 3: a target) moved by a few millimetres and tenths of a
    // degree, the brightness forgotten, every depth off by up to 8%.
    start[2].t_cw = retract_left(
        &start[2].t_cw,
        &Vector6::new(0.004, -0.003, 0.006, 0.003, -0.002, 0.002),
    );
    start[3].t_cw = retract_left(
        &start[3].t_cw,
        &Vector6::new(-0.005, 0.004, -0.008, -0.002, 0.003, -0.003),
    );
    start[3].a = 0.0;
    start[3].b = 0.0;
    let points: Vec<BundlePoint> = w
        .points
        .iter()
        .enumerate()
        .map(|(j, p)| BundlePoint {
            rho: p.rho * (1.0 + 0.08 * ((j as f64) * 1.7).sin()),
            ..*p
        })
        .collect();
    let cfg = BundleConfig {
        max_iterations: 30,
        max_start_rmse: 60.0,
        ..BundleConfig::default()
    };
    let fit = photometric_bundle(&pinhole(), &frames(&w.images, &start), &points, &cfg).unwrap();
    assert!(fit.rmse.1 < 0.2 * fit.rmse.0, "{:?}", fit.rmse);
    // Held frames stay as given.
    assert_eq!(&fit.frames[..2], &start[..2]);
    for i in 2..4 {
        let (est, truth) = (&fit.frames[i], &w.truth[i]);
        let dt = (est.t_cw.translation.vector - truth.t_cw.translation.vector).norm();
        let dr = rotation_angle_deg(&est.t_cw.rotation, &truth.t_cw.rotation);
        // Bilinear interpolation of the texture leaves about one grey level of residual at the
        // truth, and a plane seen over 30 degrees trades a turn for a sideways shift: within
        // 3 mm and 0.08 degrees (from 10 mm and 0.27 degrees).
        assert!(dt < 3e-3 && dr < 0.08, "frame {i}: {dt} m, {dr} deg");
    }
    // Gain and offset trade against each other; the mid grey level maps where it should.
    let f3 = &fit.frames[3];
    assert!((f3.a - w.truth[3].a).abs() < 0.03, "{f3:?}");
    assert!(
        (f3.a.exp() * 128.0 + f3.b - (1.1 * 128.0 + 8.0)).abs() < 0.5,
        "{f3:?}"
    );
    let mut errors: Vec<f64> = fit
        .rhos
        .iter()
        .zip(&w.points)
        .zip(&fit.outlier)
        .filter(|(_, &out)| !out)
        .map(|((rho, p), _)| (rho - p.rho).abs() / p.rho)
        .collect();
    assert!(errors.len() * 10 >= w.points.len() * 9, "{}", errors.len());
    errors.sort_by(f64::total_cmp);
    let median = errors[errors.len() / 2];
    assert!(
        median < 0.005,
        "median relative inverse-depth error {median}"
    );
}

#[test]
fn a_point_that_matches_nothing_is_an_outlier_and_an_unseen_one_is_not_judged() {
    let w = window();
    let mut points = w.points.clone();
    // The point nearest the centre, with 3 times its inverse depth, lands on unrelated
    // texture in every target (admitted: the start gate is wide open here).
    let centre = Vector2::new(80.0f32, 60.0);
    let wrong = (0..points.len())
        .min_by(|&i, &j| {
            let d = |k: usize| (points[k].pixel - centre).norm();
            d(i).total_cmp(&d(j))
        })
        .unwrap();
    points[wrong].rho *= 3.0;
    // A point whose pattern leaves its host has no observation.
    let unseen = if wrong == 1 { 0 } else { 1 };
    points[unseen].pixel = Vector2::new(0.5, 0.5);
    let cfg = BundleConfig {
        max_start_rmse: 1e3,
        ..BundleConfig::default()
    };
    let fit = photometric_bundle(&pinhole(), &frames(&w.images, &w.truth), &points, &cfg).unwrap();
    assert!(fit.outlier[wrong], "{}", fit.point_rmse[wrong]);
    assert!(fit.point_rmse[unseen].is_nan() && !fit.outlier[unseen]);
    assert_eq!(fit.rhos[unseen], points[unseen].rho);
    let inliers = fit.outlier.iter().filter(|o| !**o).count();
    assert!(
        inliers * 10 >= points.len() * 9,
        "{inliers} of {}",
        points.len()
    );
    assert!(fit.rmse.1 <= fit.rmse.0 + 1e-9, "{:?}", fit.rmse);
}

#[test]
fn bad_input_is_a_typed_error() {
    let w = window();
    let k = pinhole();
    let cfg = BundleConfig::default();
    let good = frames(&w.images, &w.truth);
    let mut points = w.points.clone();
    points[0].host = 9;
    assert!(matches!(
        photometric_bundle(&k, &good, &points, &cfg),
        Err(DirectError::InvalidConfig(_))
    ));
    points[0] = BundlePoint {
        rho: -1.0,
        ..w.points[0]
    };
    assert!(matches!(
        photometric_bundle(&k, &good, &points, &cfg),
        Err(DirectError::InvalidConfig(_))
    ));
    points[0] = BundlePoint {
        rho: f64::NAN,
        ..w.points[0]
    };
    assert!(matches!(
        photometric_bundle(&k, &good, &points, &cfg),
        Err(DirectError::NotFinite)
    ));
    let small = Image::filled(40, 30, 0.0f32);
    let mut mixed = good.clone();
    mixed[1].image = &small;
    assert!(matches!(
        photometric_bundle(&k, &mixed, &w.points, &cfg),
        Err(DirectError::SizeMismatch { .. })
    ));
    let zero = BundleConfig { huber: 0.0, ..cfg };
    assert!(matches!(
        photometric_bundle(&k, &good, &w.points, &zero),
        Err(DirectError::InvalidConfig(_))
    ));
}
