//! A fisheye image undistorted by the remap equals the pinhole image of the same scene.
//!
//! The room is ray-cast exactly (4 subsamples per pixel) through a Kannala-Brandt camera and
//! through an ideal pinhole camera with the same intrinsics `K`. The [`Undistorter`] (output
//! pixel `u` takes the fisheye image at `K D(K^-1 u)`, bilinear) must turn the first into the
//! second up to interpolation: resampling the fine room textures blurs them. The yardstick for
//! that blur is the same procedure through a radial-tangential lens of similar strength.

use vofront_core::camera::{Camera, Distortion, KannalaBrandt, Lens, Pinhole};
use vofront_direct::Undistorter;
use vofront_fixtures::scene::{pose_wc, Scene};
use vofront_image::Image;

const W: u32 = 320;
const H: u32 = 240;

/// Mean absolute difference between `a` and `b` over pixels finite in both, and the fraction
/// of such pixels.
fn mean_abs_difference(a: &Image<f32>, b: &Image<f32>) -> (f64, f64) {
    let (sum, n) = a
        .data()
        .iter()
        .zip(b.data())
        .filter(|(x, y)| x.is_finite() && y.is_finite())
        .fold((0.0, 0usize), |(s, n), (x, y)| {
            (s + f64::from((x - y).abs()), n + 1)
        });
    (sum / n.max(1) as f64, n as f64 / a.data().len() as f64)
}

/// The room at a fixed pose through `camera`.
fn render(camera: &Camera) -> Image<f32> {
    let t_wc = pose_wc([0.2, -0.1, 0.0], 0.1, -0.05, 0.02);
    Scene::box_room(11).render(camera, W, H, &t_wc).image
}

/// `image` undistorted by the remap of a camera with intrinsics `k` and lens `model_lens`.
fn undistort(k: Pinhole, model_lens: Lens, image: &Image<f32>) -> Image<f32> {
    Undistorter::new(&Camera::new(k, model_lens), W as usize, H as usize)
        .unwrap()
        .undistort_image(image)
        .unwrap()
}

#[test]
fn undistorted_fisheye_render_matches_the_pinhole_render() {
    let k = Pinhole::new(300.0, 300.0, 159.5, 119.5).unwrap();
    let truth = render(&Camera::pinhole(k));
    // A strong lens: at the image corner (34 deg) the fisheye pixel is ~30 px nearer the centre.
    let fisheye = Lens::from(KannalaBrandt::new([-0.02, 0.004, 0.0, 0.0]).unwrap());
    let raw = render(&Camera::new(k, fisheye));
    let (mean, covered) = mean_abs_difference(&undistort(k, fisheye, &raw), &truth);

    let radtan = Lens::from(Distortion::from_array([-0.2, 0.05, 0.0, 0.0, 0.0]));
    let raw_rt = render(&Camera::new(k, radtan));
    let (yardstick, _) = mean_abs_difference(&undistort(k, radtan, &raw_rt), &truth);

    let (mean_raw, _) = mean_abs_difference(&raw, &truth);
    let slightly_wrong = Lens::from(KannalaBrandt::new([-0.01, 0.004, 0.0, 0.0]).unwrap());
    let (mean_wrong, _) = mean_abs_difference(&undistort(k, slightly_wrong, &raw), &truth);
    println!(
        "mean |diff| (grey levels): fisheye {mean:.3} (covered {covered:.4}), radial-tangential \
         {yardstick:.3}, not undistorted {mean_raw:.3}, k1 off by 0.01 {mean_wrong:.3}"
    );
    // The pinhole view (34 deg to the corner) lies inside the fisheye view.
    assert!(covered > 0.98, "covered {covered}");
    // Interpolation only: within 1.5 times the radial-tangential figure (measured 3.6 vs 3.3
    // grey levels of 0-255; the fisheye compresses the periphery more, hence more blur).
    assert!(
        mean < 1.5 * yardstick,
        "fisheye {mean}, yardstick {yardstick}"
    );
    // The comparison sees the lens: without undistortion, or with k1 off by 0.01 (up to
    // ~0.6 px at the corners), the images differ more.
    assert!(
        mean_raw > 4.0 * mean,
        "raw {mean_raw} vs undistorted {mean}"
    );
    assert!(mean_wrong > mean, "wrong k1 {mean_wrong} vs {mean}");
}
