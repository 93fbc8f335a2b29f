//! Per-frame cost of the sequence trackers at 640x480: a 12-frame rendered room sequence
//! (about 1 cm and 0.3 deg per frame), tracked from the first frame; the reported time is for
//! the whole sequence, so divide by 12 for frames per second. Image decoding is excluded.
//!
//! The stereo trackers (`stereo`, `direct-stereo`): one tracked frame, the second of
//! `kitti_06` (1241x376, read from `../shared/data` relative to the workspace root) when
//! present, else of the rendered stereo drive (620x188, 1 m per frame); the tracker is built
//! and given the first frame outside the timed call.

use std::path::PathBuf;

use criterion::{criterion_group, criterion_main, BatchSize, Criterion};
use vofront::core::rig::Rig;
use vofront::dataset::{Dataset, Frame};
use vofront::odometry::direct::{DirectTracker, DirectTrackerConfig};
use vofront::odometry::feature_rgbd::{FeatureRgbdConfig, FeatureRgbdTracker};
use vofront::odometry::mono::{MonoConfig, MonoTracker};
use vofront::odometry::registry::{TrackerKind, TrackerOptions};
use vofront::odometry::Tracker;
use vofront_fixtures::image2d::to_gray8;
use vofront_fixtures::scene::{default_camera, room_trajectory, Scene};
use vofront_fixtures::stereo::StereoSequence;

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

/// The first two stereo frames of `kitti_06` and its rig when readable, else of the rendered
/// drive.
fn stereo_frames() -> (&'static str, Rig, Vec<Frame>) {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data/kitti_06");
    let kitti = Dataset::open(&root).ok().and_then(|d| {
        let frames: Option<Vec<Frame>> = (0..2).map(|i| d.load_stereo(i).ok()).collect();
        Some((d.rig?, frames?))
    });
    if let Some((rig, frames)) = kitti.filter(|(rig, _)| rig.is_stereo()) {
        return ("kitti_06_1241x376", rig, frames);
    }
    eprintln!(
        "kitti_06 not readable under {}: the rendered drive",
        root.display()
    );
    let drive = StereoSequence::driving(3, 2);
    let rig = Rig::stereo(
        drive.camera,
        Default::default(),
        drive.camera,
        drive.right_in_left(),
    )
    .expect("a stereo rig");
    let frames = (0..2)
        .map(|i| {
            let view = drive.render(i);
            Frame::new(
                i as f64 / drive.frame_rate,
                to_gray8(&view.left.image),
                None,
            )
            .and_then(|f| f.with_right(to_gray8(&view.right.image)))
            .expect("same-sized images")
        })
        .collect();
    ("rendered_620x188", rig, frames)
}

fn stereo_trackers(c: &mut Criterion) {
    let (name, rig, frames) = stereo_frames();
    let mut group = c.benchmark_group(format!("stereo_one_frame_{name}"));
    group.sample_size(10);
    for kind in [TrackerKind::Stereo, TrackerKind::DirectStereo] {
        let start = || {
            let mut tracker = kind
                .build_for_rig(&rig, &TrackerOptions::default())
                .expect("default config");
            tracker.track(&frames[0]);
            tracker
        };
        group.bench_function(kind.name(), |b| {
            b.iter_batched(
                start,
                |mut tracker| tracker.track(&frames[1]).status,
                BatchSize::PerIteration,
            )
        });
    }
    group.finish();
}

criterion_group!(benches, trackers, stereo_trackers);
criterion_main!(benches);
