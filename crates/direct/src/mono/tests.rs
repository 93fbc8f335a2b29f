//! The depth filter fed by epipolar searches converges to the true inverse depth of a
//! rendered textured plane (exact ground truth), and bad input gives typed errors.

use nalgebra::{Isometry3, Vector2, Vector3};
use vofront_core::Pinhole;
use vofront_image::Image;

use super::*;

pub(crate) const W: usize = 160;
pub(crate) const H: usize = 120;
/// The plane `Z = DEPTH` of the reference camera.
pub(crate) const DEPTH: f64 = 2.0;

pub(crate) fn pinhole() -> Pinhole {
    Pinhole::new(300.0, 300.0, 79.5, 59.5).unwrap()
}

fn texture(x: f64, y: f64) -> f64 {
    128.0
        + 40.0 * (40.0 * x).sin() * (33.0 * y).cos()
        + 25.0 * (95.0 * (x + 0.6 * y)).sin()
        + 20.0 * (70.0 * (y - 0.3 * x)).cos()
}

/// The plane seen by a camera at `T_cur_ref`: each pixel's ray cut with `Z = DEPTH`.
pub(crate) fn render(t_cur_ref: &Isometry3<f64>) -> Image<f32> {
    let k = pinhole();
    let t_ref_cur = t_cur_ref.inverse();
    let c = t_ref_cur.translation.vector;
    let data = (0..W * H)
        .map(|i| {
            let (u, v) = ((i % W) as f64, (i / W) as f64);
            let d = t_ref_cur.rotation * Vector3::new((u - k.cx) / k.fx, (v - k.cy) / k.fy, 1.0);
            let s = (DEPTH - c.z) / d.z;
            let p = c + d * s;
            texture(p.x, p.y) as f32
        })
        .collect();
    Image::new(W, H, data).unwrap()
}

/// A camera moving sideways and forward with a small turn, `i` steps from the reference.
pub(crate) fn pose(i: usize) -> Isometry3<f64> {
    let s = i as f64;
    Isometry3::new(
        Vector3::new(-0.03 * s, 0.01 * s, -0.02 * s),
        Vector3::new(0.0, 0.004 * s, 0.002 * s),
    )
}

#[test]
fn filtered_epipolar_searches_converge_to_the_true_inverse_depth() {
    let k = pinhole();
    let reference = render(&Isometry3::identity());
    let candidates = select_points(&reference, &SelectConfig::default()).unwrap();
    assert!(candidates.len() > 60, "{}", candidates.len());
    let rules = DepthRules::default();
    // Prior: depth unknown between 0.5 and infinity around a guess of 1.
    let mut points: Vec<MonoPoint> = candidates
        .iter()
        .map(|c| MonoPoint::immature(c, 1.0, 0.5))
        .collect();
    let selected = points.len();
    for i in 1..=6 {
        let t = pose(i);
        let current = render(&t);
        let pair = EpipolarPair {
            reference: &reference,
            current: &current,
            pinhole: &k,
            t_cur_ref: &t,
        };
        refine_points(&mut points, &pair, &rules);
    }
    let truth = 1.0 / DEPTH;
    let active: Vec<&MonoPoint> = points.iter().filter(|p| rules.is_active(p)).collect();
    assert!(
        active.len() * 10 >= selected * 7,
        "{} of {selected} converged",
        active.len()
    );
    let mut errors: Vec<f64> = active
        .iter()
        .map(|p| (p.filter.rho - truth).abs() / truth)
        .collect();
    errors.sort_by(f64::total_cmp);
    let median = errors[errors.len() / 2];
    assert!(median < 0.01, "median relative error {median}");
    let within = active
        .iter()
        .filter(|p| (p.filter.rho - truth).abs() <= 3.0 * p.filter.sigma() + 1e-3)
        .count();
    assert!(
        within * 10 >= active.len() * 9,
        "{within} of {} within 3 sigma",
        active.len()
    );
    // Their sparse reference aligns the last frame back to its pose.
    let active = active_points(&points, &rules);
    let cfg = crate::Se3Config::default();
    let reference =
        crate::Se3Reference::from_inverse_depths(&reference, k, None, &active, &cfg).unwrap();
    let fit = reference.align(&render(&pose(6)), &pose(5), &cfg).unwrap();
    let error = (fit.pose.translation.vector - pose(6).translation.vector).norm();
    assert!(error < 2e-3, "{error}");
}

#[test]
fn one_search_measures_the_depth_of_one_pixel() {
    let k = pinhole();
    let reference = render(&Isometry3::identity());
    let t = pose(2);
    let current = render(&t);
    let pair = EpipolarPair {
        reference: &reference,
        current: &current,
        pinhole: &k,
        t_cur_ref: &t,
    };
    let grads = reference.gradients();
    let (x, y) = (70usize, 50usize);
    let gradient = Vector2::new(f64::from(grads.gx.at(x, y)), f64::from(grads.gy.at(x, y)));
    let pixel = Vector2::new(x as f64, y as f64);
    let m = pair
        .search(pixel, gradient, (0.05, 2.0), &EpipolarConfig::default())
        .unwrap();
    assert!((m.inverse_depth - 0.5).abs() < 0.02, "{m:?}");
    // One pixel along the segment is 1 / (f b) = 0.046 of inverse depth at this baseline; the
    // gradient's angle to the segment widens it.
    assert!(m.variance > 0.0 && m.variance.sqrt() < 0.2, "{m:?}");
    assert!((m.inverse_depth - 0.5).abs() < m.variance.sqrt(), "{m:?}");
    let cfg = EpipolarConfig::default();
    assert_eq!(
        pair.search(pixel, gradient, (1.0, 0.5), &cfg),
        Err(EpipolarError::BadRange)
    );
    assert!(matches!(
        pair.search(pixel, gradient, (0.0, 1e3), &cfg),
        Err(EpipolarError::TooLong { .. })
    ));
    let still = Isometry3::identity();
    // No motion: the segment is one point, which measures no depth.
    let same = EpipolarPair {
        current: &reference,
        t_cur_ref: &still,
        ..pair
    };
    assert_eq!(
        same.search(pixel, gradient, (0.1, 1.0), &cfg),
        Err(EpipolarError::Degenerate)
    );
}
