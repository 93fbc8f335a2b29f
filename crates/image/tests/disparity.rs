//! Semi-dense disparity against rendered stereo pairs with exact depth (disparity `f b / Z`).

use nalgebra::{Isometry3, Translation3};
use vofront_fixtures::driving::DrivingSequence;
use vofront_fixtures::scene::{default_camera, room_trajectory, Scene};

use vofront_image::disparity::{match_pixels, select_pixels, DisparityConfig};
use vofront_image::{Image, ImageError};

/// Matches of the selected pixels of a rendered pair against the disparities `f b / Z` of
/// the left depth map: (selected, matched, errors of the matched in pixels).
fn against_truth(
    left: &Image<f32>,
    right: &Image<f32>,
    depth: &Image<f32>,
    fb: f32,
) -> (usize, usize, Vec<f32>) {
    let cfg = DisparityConfig::default();
    let pixels = select_pixels(left, &cfg);
    let found = match_pixels(left, right, &pixels, &cfg).unwrap();
    let errors: Vec<f32> = found
        .iter()
        .flatten()
        .map(|m| {
            let z = depth.at(m.x as usize, m.y as usize);
            assert!(m.sigma > 0.0 && m.sigma.is_finite(), "{m:?}");
            (m.disparity - fb / z).abs()
        })
        .collect();
    (pixels.len(), errors.len(), errors)
}

fn median(mut v: Vec<f32>) -> f32 {
    v.sort_by(f32::total_cmp);
    v[v.len() / 2]
}

#[test]
fn rendered_street_disparities_are_recovered_to_a_tenth_of_a_pixel() {
    let drive = DrivingSequence::new(5, 1);
    let baseline = 0.5;
    let right_in_left = Isometry3::from(Translation3::new(baseline, 0.0, 0.0));
    let (w, h) = drive.size;
    let left = drive.render(0);
    let right = drive
        .scene
        .render(&drive.camera, w, h, &(drive.poses_wc[0] * right_in_left));
    let fb = (drive.camera.pinhole.fx * baseline) as f32;
    let (selected, matched, errors) = against_truth(&left.image, &right.image, &left.depth, fb);
    assert!(selected > 1000, "{selected} pixels selected");
    assert!(matched * 2 > selected, "{matched} of {selected} matched");
    let gross = errors.iter().filter(|e| **e > 1.0).count();
    assert!(
        gross * 50 < matched,
        "{gross} of {matched} off by more than 1 px"
    );
    let med = median(errors);
    assert!(med < 0.1, "median error {med} px");
}

#[test]
fn rendered_room_disparities_are_recovered_to_a_tenth_of_a_pixel() {
    let camera = default_camera();
    let baseline = 0.1;
    let pose = room_trajectory(1)[0];
    let right_in_left = Isometry3::from(Translation3::new(baseline, 0.0, 0.0));
    let room = Scene::box_room(3);
    let left = room.render(&camera, 640, 480, &pose);
    let right = room.render(&camera, 640, 480, &(pose * right_in_left));
    let fb = (camera.pinhole.fx * baseline) as f32;
    let (selected, matched, errors) = against_truth(&left.image, &right.image, &left.depth, fb);
    assert!(matched * 2 > selected, "{matched} of {selected} matched");
    let gross = errors.iter().filter(|e| **e > 1.0).count();
    assert!(
        gross * 50 < matched,
        "{gross} of {matched} off by more than 1 px"
    );
    let med = median(errors);
    assert!(med < 0.1, "median error {med} px");
}

#[test]
fn a_periodic_row_is_ambiguous_and_a_flat_one_has_no_pixels() {
    let (w, h) = (160, 20);
    // Period 8 pixels: every shift by 8 matches as well as the true one.
    let periodic = Image::new(
        w,
        h,
        (0..w * h)
            .map(|i| 100.0 + 60.0 * ((i % w) as f32 * std::f32::consts::TAU / 8.0).sin())
            .collect(),
    )
    .unwrap();
    let cfg = DisparityConfig::default();
    let pixels = select_pixels(&periodic, &cfg);
    assert!(!pixels.is_empty());
    let found = match_pixels(&periodic, &periodic, &pixels, &cfg).unwrap();
    assert!(
        found.iter().all(Option::is_none),
        "periodic texture matched"
    );
    let flat = Image::filled(w, h, 90.0f32);
    assert!(select_pixels(&flat, &cfg).is_empty());
}

#[test]
fn bad_settings_and_sizes_are_refused() {
    let img = Image::filled(40, 20, 1.0f32);
    let other = Image::filled(41, 20, 1.0f32);
    let cfg = DisparityConfig::default();
    assert!(matches!(
        match_pixels(&img, &other, &[], &cfg),
        Err(ImageError::SizeMismatch { .. })
    ));
    for bad in [
        DisparityConfig {
            min_disparity: 0,
            ..cfg
        },
        DisparityConfig {
            max_disparity: 1,
            ..cfg
        },
        DisparityConfig {
            uniqueness: 0.0,
            ..cfg
        },
        DisparityConfig { radius: 0, ..cfg },
        DisparityConfig {
            max_mean_cost: f32::NAN,
            ..cfg
        },
    ] {
        assert!(
            matches!(
                match_pixels(&img, &img, &[], &bad),
                Err(ImageError::InvalidConfig(_))
            ),
            "{bad:?}"
        );
    }
}
