//! Every aligner returns its result with the verdict already judged, with the `quality`
//! thresholds of the configuration it was given.

use nalgebra::{Isometry3, Matrix3};
use vofront_direct::{
    align_affine, align_se3, align_translation, RgbdFrame, Se3Config, Se3Reference,
    TranslationConfig, WarpConfig,
};
use vofront_fixtures::image2d::{
    gaussian_blur, textured_image, translation, warped_textured_image,
};
use vofront_fixtures::scene::{default_camera, pose_wc, Scene};
use vofront_image::Image;
use vofront_robust::{QualityConfig, Reason, Verdict};

const W: u32 = 320;
const H: u32 = 240;

/// Thresholds no estimate can meet: more valid pixels than any image has.
fn unreachable_pixels() -> QualityConfig {
    QualityConfig {
        min_pixels: usize::MAX,
        ..QualityConfig::default()
    }
}

fn shifted_pair() -> (Image<f32>, Image<f32>) {
    let i1 = gaussian_blur(&textured_image(W, H, 5), 1.0);
    let i2 = gaussian_blur(
        &warped_textured_image(W, H, 5, &translation(1.5, -0.75)),
        1.0,
    );
    (i1, i2)
}

#[test]
fn translation_is_judged_with_its_config() {
    let (p1, p2) = shifted_pair();
    let fit = align_translation(&p1, &p2, &TranslationConfig::default()).unwrap();
    assert_eq!(
        fit.quality.verdict,
        Verdict::Ok,
        "{:?}",
        fit.quality.reasons
    );
    let pixels = (fit.used_fraction * (W * H) as f64).round() as usize;
    assert_eq!(fit.quality.support.pixels, Some(pixels));
    assert!(fit.quality.uncertainty.shift_sigma_px.is_some());
    let strict = TranslationConfig {
        quality: unreachable_pixels(),
        ..TranslationConfig::default()
    };
    let judged = align_translation(&p1, &p2, &strict).unwrap();
    assert_eq!(judged.d, fit.d, "the thresholds change the verdict only");
    assert!(judged.quality.reasons.contains(&Reason::TooFewPixels));
    assert_ne!(judged.quality.verdict, Verdict::Ok);
}

#[test]
fn affine_warp_is_judged_with_its_config() {
    let (p1, p2) = shifted_pair();
    let fit = align_affine(&p1, &p2, &Matrix3::identity(), &WarpConfig::default()).unwrap();
    assert_eq!(
        fit.quality.verdict,
        Verdict::Ok,
        "{:?}",
        fit.quality.reasons
    );
    assert_eq!(fit.quality.support.candidates, (W * H) as usize);
    let strict = WarpConfig {
        quality: unreachable_pixels(),
        ..WarpConfig::default()
    };
    let judged = align_affine(&p1, &p2, &Matrix3::identity(), &strict).unwrap();
    assert!(judged.quality.reasons.contains(&Reason::TooFewPixels));
}

#[test]
fn se3_support_counts_against_the_reference_candidates() {
    let room = Scene::box_room(5);
    let camera = default_camera();
    let first = room.render(&camera, W, H, &pose_wc([0.0; 3], 0.0, 0.0, 0.0));
    let second = room.render(&camera, W, H, &pose_wc([0.03, 0.0, 0.02], 0.01, 0.0, 0.0));
    let frame = RgbdFrame::new(first.image.clone(), first.depth.clone(), &camera).unwrap();
    let current = second.image;
    let cfg = Se3Config::default();
    let prior = Isometry3::identity();
    // One-off alignment: support out of every pixel of the frame.
    let dense = align_se3(&frame, &current, &prior, &cfg).unwrap();
    assert_eq!(
        dense.quality.verdict,
        Verdict::Ok,
        "{:?}",
        dense.quality.reasons
    );
    assert_eq!(dense.quality.support.candidates, (W * H) as usize);
    assert_eq!(dense.quality.support.pixels, Some(dense.valid_pixels));
    assert!(dense.quality.uncertainty.rotation_sigma_deg.is_some());
    // A prepared reference: support out of its selected pixels.
    let reference = Se3Reference::new(&frame, &cfg).unwrap();
    let fit = reference.align(&current, &prior, &cfg).unwrap();
    let selected = reference.selected()[0];
    assert!(selected < (W * H) as usize);
    assert_eq!(
        fit.quality.support.candidates,
        selected.max(fit.valid_pixels)
    );
    assert_eq!(fit.pose, dense.pose, "the reference is the same");
    let strict = Se3Config {
        quality: unreachable_pixels(),
        ..cfg
    };
    let judged = reference.align(&current, &prior, &strict).unwrap();
    assert!(judged.quality.reasons.contains(&Reason::TooFewPixels));
}
