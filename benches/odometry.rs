//! Per-frame cost of the sequence trackers at 640x480: a 12-frame rendered room sequence
//! (about 1 cm and 0.3 deg per frame), tracked from the first frame; the reported time is for
//! the whole sequence, so divide by 12 for frames per second. Image decoding is excluded.

use criterion::{criterion_group, criterion_main, Criterion};
use vofront::dataset::Frame;
use vofront::odometry::direct::{DirectTracker, DirectTrackerConfig};
use vofront::odometry::feature_rgbd::{FeatureRgbdConfig, FeatureRgbdTracker};
use vofront::odometry::mono::{MonoConfig, MonoTracker};
use vofront::odometry::Tracker;
use vofront_fixtures::image2d::to_gray8;
use vofront_fixtures::scene::{default_camera, room_trajectory, Scene};

const FRAMES: usize = 12;

fn frames() -> Vec<Frame> {
    let room = Scene::box_room(1);
    room_trajectory(FRAMES)
        .iter()
        .enumerate()
        .map(|(i, pose)| {
            let view = room.render(&default_camera(), 640, 480, pose);
            Frame::new(i as f64 / 30.0, to_gray8(&view.image), Some(view.depth))
                .expect("rendered depth has the image's size")
        })
        .collect()
}

fn track_all(tracker: &mut dyn Tracker, frames: &[Frame]) -> usize {
    frames
        .iter()
        .filter(|f| tracker.track(f).status != vofront::odometry::TrackStatus::Lost)
        .count()
}

fn trackers(c: &mut Criterion) {
    let frames = frames();
    let camera = default_camera();
    let mut group = c.benchmark_group("odometry_12_frames_640x480");
    group.sample_size(10);
    group.bench_function("direct", |b| {
        b.iter(|| {
            track_all(
                &mut DirectTracker::new(camera, DirectTrackerConfig::default()),
                &frames,
            )
        })
    });
    group.bench_function("feature_rgbd", |b| {
        b.iter(|| {
            let mut tracker = FeatureRgbdTracker::new(camera, FeatureRgbdConfig::default())
                .expect("default config");
            track_all(&mut tracker, &frames)
        })
    });
    group.bench_function("feature_mono", |b| {
        b.iter(|| {
            let mut tracker =
                MonoTracker::new(camera, MonoConfig::default()).expect("default config");
            track_all(&mut tracker, &frames)
        })
    });
    group.finish();
}

criterion_group!(benches, trackers);
criterion_main!(benches);
