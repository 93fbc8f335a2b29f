//! Criterion benchmark of stereo matching (`match_stereo`) between the ORB features of the two
//! images of a rectified pair: `kitti_06` frame 0 (`image_0`, `image_1`, 1226x370, read from
//! `../shared/data` relative to the workspace root) when present, else a rendered street pair.
//! The ORB detection of both images is outside the timed loop.
//!
//! The semi-dense disparity of the direct path (`vofront_image::disparity`) on the same pair:
//! selection and block matching with the left-right check, timed together.

use std::path::PathBuf;

use criterion::{criterion_group, criterion_main, Criterion};
use nalgebra::Translation3;
use vofront_features::{match_stereo, Orb, OrbConfig, StereoConfig};
use vofront_fixtures::driving::DrivingSequence;
use vofront_fixtures::image2d::to_gray8;
use vofront_image::disparity::{match_pixels, select_pixels, DisparityConfig};
use vofront_image::Image;

/// The KITTI pair when readable, else a rendered one.
fn pair() -> (&'static str, Image<u8>, Image<u8>) {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/kitti_06");
    let read = |cam: &str| {
        image::open(root.join(cam).join("000000.png")).map(|i| Image::from_gray_owned(i.to_luma8()))
    };
    match (read("image_0"), read("image_1")) {
        (Ok(l), Ok(r)) => ("kitti_06", l, r),
        _ => {
            eprintln!(
                "kitti_06 not readable under {}: a rendered pair",
                root.display()
            );
            let drive = DrivingSequence::new(3, 1);
            let (w, h) = drive.size;
            let right = drive.poses_wc[0] * Translation3::new(0.54, 0.0, 0.0);
            let render = |pose| to_gray8(&drive.scene.render(&drive.camera, w, h, pose).image);
            ("rendered", render(&drive.poses_wc[0]), render(&right))
        }
    }
}

fn stereo(c: &mut Criterion) {
    let (name, left, right) = pair();
    let orb = Orb::new(OrbConfig::default()).expect("valid config");
    let fl = orb.detect_and_describe(&left).expect("ORB");
    let fr = orb.detect_and_describe(&right).expect("ORB");
    let cfg = StereoConfig::default();
    let n = match_stereo(&fl, &fr, &left, &right, &cfg).map_or(0, |m| m.len());
    eprintln!("{name}: {n} stereo matches of {} left features", fl.len());
    c.bench_function(&format!("match_stereo_{name}"), |b| {
        b.iter(|| match_stereo(&fl, &fr, &left, &right, &cfg).map(|m| m.len()))
    });
}

fn semi_dense(c: &mut Criterion) {
    let (name, left, right) = pair();
    let (left, right) = (left.to_f32(), right.to_f32());
    let cfg = DisparityConfig::default();
    let pixels = select_pixels(&left, &cfg);
    let n = match_pixels(&left, &right, &pixels, &cfg).map_or(0, |m| m.iter().flatten().count());
    eprintln!(
        "{name}: {n} disparities of {} selected pixels",
        pixels.len()
    );
    c.bench_function(&format!("semi_dense_disparity_{name}"), |b| {
        b.iter(|| {
            let pixels = select_pixels(&left, &cfg);
            match_pixels(&left, &right, &pixels, &cfg).map(|m| m.len())
        })
    });
}

criterion_group!(benches, stereo, semi_dense);
criterion_main!(benches);
