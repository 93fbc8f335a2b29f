//! Criterion benchmarks at 640x480 on the fixtures:
//! - `translation_640x480`: [`align_translation`] with the default 4 levels and at most 20000
//!   pixels at full resolution, the same density at the coarser levels (inverse compositional
//!   and forward additive);
//! - `se3_640x480`: [`align_se3`] on two box-room renders, 4 levels, 12000-cell budget per
//!   level (about 8500 pixels selected at each of the two finest levels), affine brightness,
//!   Huber (reference preparation included, as for the peer);
//! - `klt_500`: [`track_klt`] of 500 Shi-Tomasi corners, 21x21 window, 4 levels, without and
//!   with the forward-backward check.

use criterion::{criterion_group, criterion_main, Criterion};
use nalgebra::Isometry3;
use vofront_direct::{
    align_se3, align_translation, good_features_to_track, track_klt, KltConfig, RgbdFrame,
    Se3Config, TranslationConfig, TranslationMethod,
};
use vofront_fixtures::image2d::{
    gaussian_blur, textured_image, translation, warped_textured_image,
};
use vofront_fixtures::scene::{default_camera, pose_wc, Scene};
use vofront_image::Image;

fn shifted_pair() -> (Image<f32>, Image<f32>) {
    let i1 = gaussian_blur(&textured_image(640, 480, 1), 1.0);
    let i2 = gaussian_blur(
        &warped_textured_image(640, 480, 1, &translation(2.3, -1.7)),
        1.0,
    );
    (i1, i2)
}

fn bench_translation(c: &mut Criterion) {
    let (i1, i2) = shifted_pair();
    for method in [
        TranslationMethod::InverseCompositional,
        TranslationMethod::ForwardAdditive,
    ] {
        let cfg = TranslationConfig {
            method,
            ..TranslationConfig::default()
        };
        c.bench_function(&format!("translation_640x480_{method:?}"), |b| {
            b.iter(|| align_translation(&i1, &i2, &cfg).expect("textured pair"))
        });
    }
}

fn bench_se3(c: &mut Criterion) {
    let camera = default_camera();
    let room = Scene::box_room(5);
    let first = room.render(&camera, 640, 480, &pose_wc([0.0, 0.0, 0.0], 0.0, 0.0, 0.0));
    let second = room.render(
        &camera,
        640,
        480,
        &pose_wc([0.04, -0.025, 0.06], 0.025, -0.015, 0.01),
    );
    let image = first.image;
    let depth = first.depth.clone();
    let current = second.image;
    let cfg = Se3Config::default();
    c.bench_function("se3_640x480", |b| {
        b.iter(|| {
            let reference =
                RgbdFrame::new(image.clone(), depth.clone(), &camera).expect("valid frame");
            align_se3(&reference, &current, &Isometry3::identity(), &cfg).expect("aligns")
        })
    });
}

fn bench_klt(c: &mut Criterion) {
    let (i1, i2) = shifted_pair();
    let corners = good_features_to_track(&i1, 500, 0.01, 8.0);
    c.bench_function("gftt_640x480_500", |b| {
        b.iter(|| good_features_to_track(&i1, 500, 0.01, 8.0))
    });
    let plain = KltConfig {
        forward_backward: None,
        ..KltConfig::default()
    };
    c.bench_function("klt_500", |b| {
        b.iter(|| track_klt(&i1, &i2, &corners, &plain).expect("same size"))
    });
    c.bench_function("klt_500_forward_backward", |b| {
        b.iter(|| track_klt(&i1, &i2, &corners, &KltConfig::default()).expect("same size"))
    });
}

criterion_group!(benches, bench_translation, bench_se3, bench_klt);
criterion_main!(benches);
