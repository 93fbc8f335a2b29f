//! 2D alignment on exact synthetic warps of the fixtures' texture.

use nalgebra::{Matrix3, Vector2};
use proptest::prelude::*;
use vofront_direct::{
    align_affine, align_homography, align_translation, DirectError, TranslationConfig,
    TranslationMethod, WarpConfig,
};
use vofront_fixtures::image2d::{
    add_gaussian_noise, brightness, gaussian_blur, similarity, textured_image, translation,
    warped_textured_image,
};
use vofront_image::Image;
use vofront_robust::{Loss, SolveError};

/// Noiseless sub-pixel shifts must be recovered to this, pixels (the brief's requirement).
const NOISELESS_TOLERANCE: f64 = 0.02;
/// With 2 grey levels of noise, pixels.
const NOISY_TOLERANCE: f64 = 0.1;
const W: u32 = 320;
const H: u32 = 240;

/// A pair `I1`, `I2` with `I2(x + d) = I1(x)`, both blurred with sigma 1 (the texture's hard
/// shape edges alias otherwise and bias any interpolating method).
fn shifted_pair(seed: u64, dx: f64, dy: f64) -> (Image<f32>, Image<f32>) {
    let i1 = gaussian_blur(&textured_image(W, H, seed), 1.0);
    let i2 = gaussian_blur(
        &warped_textured_image(W, H, seed, &translation(dx, dy)),
        1.0,
    );
    (i1, i2)
}

fn error(d: Vector2<f64>, dx: f64, dy: f64) -> f64 {
    (d - Vector2::new(dx, dy)).norm()
}

#[test]
fn noiseless_subpixel_shift_is_recovered_by_both_methods() {
    let (i1, i2) = shifted_pair(3, 2.37, -1.61);
    for method in [
        TranslationMethod::InverseCompositional,
        TranslationMethod::ForwardAdditive,
    ] {
        let cfg = TranslationConfig {
            method,
            ..TranslationConfig::default()
        };
        let fit = align_translation(&i1, &i2, &cfg).unwrap();
        let e = error(fit.d, 2.37, -1.61);
        assert!(e < NOISELESS_TOLERANCE, "{method:?}: {:?} error {e}", fit.d);
        assert!(fit.converged);
        // About `max_pixels` (20000) of the 76800 pixels.
        assert!(fit.used_fraction > 0.2, "{}", fit.used_fraction);
        let c = fit.covariance.expect("a known covariance");
        assert!(c[(0, 0)] > 0.0 && c[(0, 0)] < 1e-3);
    }
}

/// Threshold 0 and no pixel limit: every interior pixel is a reference pixel (the border
/// ones have no central difference and must never be chosen).
#[test]
fn zero_threshold_without_budget_uses_every_interior_pixel() {
    let (i1, i2) = shifted_pair(4, -1.23, 0.77);
    let cfg = TranslationConfig {
        gradient_threshold: 0.0,
        max_pixels: 0,
        ..TranslationConfig::default()
    };
    let fit = align_translation(&i1, &i2, &cfg).unwrap();
    let e = error(fit.d, -1.23, 0.77);
    assert!(e < NOISELESS_TOLERANCE, "{:?} error {e}", fit.d);
    let interior = ((W - 2) * (H - 2)) as f64 / (W * H) as f64;
    assert!(
        fit.used_fraction > 0.95 * interior && fit.used_fraction <= interior,
        "{}",
        fit.used_fraction
    );
}

#[test]
fn noisy_shift_is_recovered_and_covariance_is_consistent() {
    let (i1, i2) = shifted_pair(5, -3.3, 4.45);
    let n1 = add_gaussian_noise(&i1, 2.0, 1);
    let n2 = add_gaussian_noise(&i2, 2.0, 2);
    let fit = align_translation(&n1, &n2, &TranslationConfig::default()).unwrap();
    let e = error(fit.d, -3.3, 4.45);
    assert!(e < NOISY_TOLERANCE, "{:?} error {e}", fit.d);
    // The residual is the difference of two noisy images (sigma 2 sqrt 2) after the sigma-1
    // binomial presmoothing, which scales white noise by 70/256 = 0.273: about 0.77 grey.
    assert!(fit.rmse > 0.5 && fit.rmse < 2.0, "{}", fit.rmse);
}

#[test]
fn brightness_change_needs_the_affine_brightness_model() {
    let i1 = gaussian_blur(&textured_image(W, H, 7), 1.0);
    let i2 = gaussian_blur(&warped_textured_image(W, H, 7, &translation(1.7, 0.8)), 1.0);
    let i2 = brightness(&i2, 1.3, -20.0);
    let (p1, p2) = (i1, i2);
    let on = align_translation(
        &p1,
        &p2,
        &TranslationConfig {
            affine_brightness: true,
            ..TranslationConfig::default()
        },
    )
    .unwrap();
    let e_on = error(on.d, 1.7, 0.8);
    assert!(e_on < NOISELESS_TOLERANCE, "{:?} {e_on}", on.d);
    // Gain and offset are correlated; the gain and the brightness of mid-grey are checked.
    let mid_grey_error = (on.a * 128.0 + on.b) - (1.3 * 128.0 - 20.0);
    assert!(
        (on.a - 1.3).abs() < 0.02 && mid_grey_error.abs() < 1.0,
        "{} {}",
        on.a,
        on.b
    );
    let off = align_translation(&p1, &p2, &TranslationConfig::default());
    // Without the brightness model the residuals are large: either a worse shift or a
    // residual RMSE many times higher.
    match off {
        Ok(off) => assert!(
            error(off.d, 1.7, 0.8) > 2.0 * e_on && off.rmse > 5.0 * on.rmse,
            "off {:?} rmse {} vs {}",
            off.d,
            off.rmse,
            on.rmse
        ),
        Err(e) => panic!("L2-free model should still run: {e}"),
    }
}

#[test]
fn flat_image_is_no_texture_and_stripes_are_degenerate() {
    let flat = Image::filled(64, 48, 100.0);
    assert!(matches!(
        align_translation(&flat, &flat, &TranslationConfig::default()),
        Err(DirectError::NoTexture { .. })
    ));
    // Vertical stripes: every gradient is horizontal (the aperture problem).
    let stripes = Image::new(
        64,
        48,
        (0..64 * 48)
            .map(|i| 100.0 + 60.0 * ((i % 64) as f32 * 0.4).sin())
            .collect(),
    )
    .unwrap();
    let err = align_translation(&stripes, &stripes, &TranslationConfig::default()).unwrap_err();
    assert!(
        matches!(err, DirectError::Solve(SolveError::Degenerate { .. })),
        "{err:?}"
    );
}

#[test]
fn size_mismatch_is_an_error() {
    let a = Image::filled(64, 48, 1.0);
    let b = Image::filled(48, 64, 1.0);
    assert!(matches!(
        align_translation(&a, &b, &TranslationConfig::default()),
        Err(DirectError::SizeMismatch { .. })
    ));
}

#[test]
fn homography_is_recovered() {
    let h_true = Matrix3::new(1.02, 0.03, -2.5, -0.02, 0.99, 1.8, 4e-5, -3e-5, 1.0);
    let i1 = gaussian_blur(&textured_image(W, H, 11), 1.0);
    let i2 = gaussian_blur(&warped_textured_image(W, H, 11, &h_true), 1.0);
    let cfg = WarpConfig {
        loss: Loss::Huber(1.345),
        ..WarpConfig::default()
    };
    let fit = align_homography(&i1, &i2, &Matrix3::identity(), &cfg).unwrap();
    let worst = corner_error(&fit.h, &h_true);
    assert!(worst < 0.05, "corner error {worst} px, H = {}", fit.h);
}

/// Largest distance between where two homographies send the image corners and center, pixels.
fn corner_error(a: &Matrix3<f64>, b: &Matrix3<f64>) -> f64 {
    let (w, h) = (f64::from(W - 1), f64::from(H - 1));
    [(0.0, 0.0), (w, 0.0), (0.0, h), (w, h), (w / 2.0, h / 2.0)]
        .iter()
        .map(|&(x, y)| {
            let p = |m: &Matrix3<f64>| {
                let v = m * nalgebra::Vector3::new(x, y, 1.0);
                Vector2::new(v.x / v.z, v.y / v.z)
            };
            (p(a) - p(b)).norm()
        })
        .fold(0.0, f64::max)
}

#[test]
fn affine_warp_with_brightness_change_is_recovered() {
    let truth = similarity(0.05, 1.03, 160.0, 120.0, 1.6, -2.2);
    let i1 = gaussian_blur(&textured_image(W, H, 13), 1.0);
    let i2 = brightness(
        &gaussian_blur(&warped_textured_image(W, H, 13, &truth), 1.0),
        1.2,
        10.0,
    );
    let (p1, p2) = (i1, i2);
    let on = WarpConfig {
        affine_brightness: true,
        ..WarpConfig::default()
    };
    let fit = align_affine(&p1, &p2, &Matrix3::identity(), &on).unwrap();
    let err = corner_error(&fit.h, &truth);
    assert!(err < 0.05, "corner error {err} px, H = {}", fit.h);
    assert!((fit.a - 1.2).abs() < 0.02, "{} {}", fit.a, fit.b);
    assert_eq!(fit.covariance.map(|c| c.shape()), Some((6, 6)));
    // Without the brightness model the fit is visibly worse or fails.
    let off = align_affine(&p1, &p2, &Matrix3::identity(), &WarpConfig::default());
    if let Ok(off) = off {
        assert!(off.rmse > 3.0 * fit.rmse, "{} vs {}", off.rmse, fit.rmse);
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(vofront_fixtures::proptest_cases(12)))]
    #[test]
    fn random_subpixel_shifts_are_recovered(dx in -4.0f64..4.0, dy in -4.0f64..4.0, seed in 0u64..1000) {
        let (i1, i2) = shifted_pair(seed, dx, dy);
        let fit = align_translation(&i1, &i2, &TranslationConfig::default()).unwrap();
        prop_assert!(error(fit.d, dx, dy) < NOISELESS_TOLERANCE, "{:?} vs ({dx}, {dy})", fit.d);
    }
}
