//! The lesson's two-view pipeline, warm: ORB on both frames, kNN-2 matching, the relative pose
//! with its quality record ([`TwoViewEstimator::relative_pose`], what `vofront two-view --method
//! feature` runs after decoding). On TUM `case_1` (640x480, the `tum-fr1` preset, read from
//! `../shared/data` relative to the workspace root) when present, else on a rendered room
//! pair. The peer is `opencv_peer.py twoview`, also warm (median of repetitions in one
//! process); image decoding is excluded from both.

use std::path::PathBuf;

use criterion::{criterion_group, criterion_main, Criterion};
use vofront::input::load_gray;
use vofront::pipeline::TwoViewEstimator;
use vofront::presets::camera_preset;
use vofront_fixtures::image2d::to_gray8;
use vofront_fixtures::scene::{default_camera, pose_wc, Scene};
use vofront_geometry::Camera;
use vofront_image::Image;

/// TUM `case_1` and its camera when readable, else a rendered room pair.
fn pair() -> (&'static str, [Image<u8>; 2], Camera) {
    let dir =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data/tum_fr1_xyz_pairs/case_1");
    let tum = load_gray(&dir.join("img_prev.png"))
        .and_then(|a| Ok([a, load_gray(&dir.join("img_curr.png"))?]));
    if let (Ok(images), Some(preset)) = (tum, camera_preset("tum-fr1")) {
        return ("tum_case_1_640x480", images, preset.camera);
    }
    eprintln!(
        "TUM case_1 not readable under {}: a rendered pair",
        dir.display()
    );
    let room = Scene::box_room(3);
    let camera = default_camera();
    let render = |pose| to_gray8(&room.render(&camera, 640, 480, &pose).image);
    let images = [
        render(pose_wc([0.0; 3], 0.0, 0.0, 0.0)),
        render(pose_wc([0.15, 0.0, 0.05], -0.04, 0.0, 0.0)),
    ];
    ("rendered_room_640x480", images, camera)
}

fn two_view(c: &mut Criterion) {
    let (name, [img1, img2], camera) = pair();
    let estimator = TwoViewEstimator::default();
    let mut group = c.benchmark_group(format!("two_view_{name}"));
    group.sample_size(20);
    group.bench_function("feature", |b| {
        b.iter(|| {
            estimator
                .relative_pose(&img1, &img2, &camera)
                .map(|fit| fit.estimate.inlier_count())
        })
    });
    group.finish();
}

criterion_group!(benches, two_view);
criterion_main!(benches);
