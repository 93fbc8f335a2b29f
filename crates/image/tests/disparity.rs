//! Semi-dense disparity against the rendered stereo fixture
//! (`vofront_fixtures::stereo`: exact disparities `f b / Z`).

use vofront_fixtures::stereo::StereoSequence;
use vofront_image::disparity::{match_pixels, select_pixels, DisparityConfig};
use vofront_image::{Image, ImageError};

/// Matches of the selected pixels of frame 0 of `sequence` against its exact disparities:
/// (selected, matched, errors of the matched in pixels).
fn against_truth(sequence: &StereoSequence) -> (usize, usize, Vec<f32>) {
    let view = sequence.render(0);
    let (left, right) = (&view.left.image, &view.right.image);
    let cfg = DisparityConfig::default();
    let pixels = select_pixels(left, &cfg);
    let found = match_pixels(left, right, &pixels, &cfg).unwrap();
    let errors: Vec<f32> = found
        .iter()
        .flatten()
        .map(|m| {
            assert!(m.sigma > 0.0 && m.sigma.is_finite(), "{m:?}");
            (m.disparity - view.disparity.at(m.x as usize, m.y as usize)).abs()
        })
        .collect();
    (pixels.len(), errors.len(), errors)
}

fn median(mut v: Vec<f32>) -> f32 {
    v.sort_by(f32::total_cmp);
    v[v.len() / 2]
}

/// Half the selected pixels matched, fewer than 2% of them off by more than a pixel
/// (occlusions and ambiguities are rejected), the median error under a tenth of a pixel.
fn check(sequence: &StereoSequence) {
    let (selected, matched, errors) = against_truth(sequence);
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
fn rendered_street_disparities_are_recovered_to_a_tenth_of_a_pixel() {
    check(&StereoSequence::driving(5, 1));
}

#[test]
fn rendered_room_disparities_are_recovered_to_a_tenth_of_a_pixel() {
    check(&StereoSequence::room(3, 1));
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
