//! Stereo datasets: the right images and the camera rig of KITTI and EuRoC folders (written
//! by the tests), and the rectification of the real EuRoC and KITTI rigs of `../shared/data`
//! (skipped when absent).

use std::fs;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use image::{GrayImage, Luma};
use nalgebra::{Isometry3, Point3, Rotation3, Vector3};
use vofront::core::rectify::StereoRectification;
use vofront::core::rig::RigError;
use vofront::dataset::{Dataset, DatasetError, DatasetKind, FrameError};
use vofront::features::{match_descriptors, MatchConfig, Orb, OrbConfig};
use vofront::image::{Image, Remap};

/// A fresh folder under the system temp dir, removed on drop.
struct TempDir(PathBuf);

impl TempDir {
    fn new(tag: &str) -> Self {
        static COUNTER: AtomicUsize = AtomicUsize::new(0);
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let dir =
            std::env::temp_dir().join(format!("vofront-stereo-{tag}-{}-{n}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).expect("temp dir");
        Self(dir)
    }

    fn write(&self, rel: &str, text: &str) {
        let path = self.0.join(rel);
        fs::create_dir_all(path.parent().expect("has parent")).expect("mkdir");
        fs::write(&path, text).expect("write");
    }

    fn grey_png(&self, rel: &str, (w, h): (u32, u32), value: u8) {
        let path = self.0.join(rel);
        fs::create_dir_all(path.parent().expect("has parent")).expect("mkdir");
        GrayImage::from_pixel(w, h, Luma([value]))
            .save(path)
            .expect("png");
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = fs::remove_dir_all(&self.0);
    }
}

// ---------------------------------------------------------------- KITTI

/// KITTI 00-02 calibration: `P1[3] = -fx b` with b = 0.5371657 m.
const KITTI_FX: f64 = 718.856;
const KITTI_BASELINE: f64 = 0.537_165_7;

fn kitti_calib() -> String {
    let p = |tx: f64| format!("{KITTI_FX} 0 607.1928 {tx} 0 {KITTI_FX} 185.2157 0 0 0 1 0");
    format!(
        "P0: {}\nP1: {}\nP2: {}\n",
        p(0.0),
        p(-KITTI_FX * KITTI_BASELINE),
        p(46.0)
    )
}

/// An excerpt of a KITTI sequence whose frames start at `000100.png`, with `image_1/`.
fn kitti_excerpt(dir: &TempDir) {
    dir.write("calib.txt", &kitti_calib());
    dir.write("times.txt", "1.0e+01\n1.0104e+01\n1.0207e+01\n");
    for i in 0..3u8 {
        let name = format!("{:06}.png", 100 + u32::from(i));
        dir.grey_png(&format!("image_0/{name}"), (12, 5), 10 + i);
        dir.grey_png(&format!("image_1/{name}"), (12, 5), 100 + i);
    }
}

#[test]
fn kitti_excerpt_pairs_sorted_images_with_times_and_reads_the_right_camera() {
    let dir = TempDir::new("kitti");
    kitti_excerpt(&dir);
    let data = Dataset::open(&dir.0).expect("open");
    assert_eq!(data.kind, DatasetKind::Kitti);
    assert_eq!(data.len(), 3);
    assert_eq!(data.frames[0].image, dir.0.join("image_0/000100.png"));
    assert_eq!(data.frames[2].image, dir.0.join("image_0/000102.png"));
    assert_eq!(
        data.frames[1].right.as_deref(),
        Some(dir.0.join("image_1/000101.png").as_path())
    );
    assert_eq!(data.frames[1].timestamp, 10.104);

    let rig = data.rig.expect("rig");
    assert!(rig.is_stereo());
    assert_eq!(rig.left(), &data.camera.expect("camera"));
    assert_eq!(rig.right().expect("right").pinhole.fx, KITTI_FX);
    assert!((rig.baseline().expect("stereo") - KITTI_BASELINE).abs() < 1e-12);
    // Body = left camera; the right camera's centre is b to its right.
    let t_rl = rig.t_right_left().expect("stereo");
    assert!((t_rl.translation.vector - Vector3::new(-KITTI_BASELINE, 0.0, 0.0)).norm() < 1e-12);
    assert_eq!(rig.left_in_body().t_bs, Isometry3::identity());

    // A monocular load reads the left image only; a stereo load reads both.
    let mono = data.load(1).expect("load");
    assert_eq!(mono.image().at(0, 0), 11);
    assert!(mono.right().is_none());
    let stereo = data.load_stereo(1).expect("load stereo");
    assert_eq!(stereo.image().at(0, 0), 11);
    assert_eq!(stereo.right().expect("right").at(11, 4), 101);
    assert_eq!(stereo.timestamp(), 10.104);
}

#[test]
fn kitti_count_mismatch_is_a_typed_error_naming_both_counts() {
    let dir = TempDir::new("kitti-count");
    kitti_excerpt(&dir);
    dir.write("times.txt", "0.0\n0.1\n0.2\n0.3\n");
    match Dataset::open(&dir.0) {
        Err(e @ DatasetError::FrameCount { .. }) => {
            let DatasetError::FrameCount { images, times, .. } = &e else {
                unreachable!()
            };
            assert_eq!((*images, *times), (3, 4));
            let message = e.to_string();
            assert!(
                message.contains("3 images") && message.contains("4 timestamps"),
                "{message}"
            );
        }
        other => panic!("expected a count mismatch, got {other:?}"),
    }
}

#[test]
fn kitti_missing_right_image_fails_at_open_and_mono_folders_have_a_mono_rig() {
    let dir = TempDir::new("kitti-right");
    kitti_excerpt(&dir);
    fs::remove_file(dir.0.join("image_1/000101.png")).expect("rm");
    match Dataset::open(&dir.0) {
        Err(DatasetError::MissingRightImage { path, left }) => {
            assert_eq!(path, dir.0.join("image_1/000101.png"));
            assert_eq!(left, dir.0.join("image_0/000101.png"));
        }
        other => panic!("expected a missing right image, got {other:?}"),
    }
    fs::remove_dir_all(dir.0.join("image_1")).expect("rm");
    let data = Dataset::open(&dir.0).expect("mono open");
    let rig = data.rig.expect("rig");
    assert!(!rig.is_stereo() && rig.baseline().is_none());
    assert!(data.frames.iter().all(|f| f.right.is_none()));
    assert!(matches!(
        data.load_stereo(0),
        Err(DatasetError::NoRightImage { index: 0 })
    ));
}

#[test]
fn kitti_right_image_of_another_size_fails_that_stereo_frame() {
    let dir = TempDir::new("kitti-size");
    kitti_excerpt(&dir);
    dir.grey_png("image_1/000102.png", (11, 5), 7);
    let data = Dataset::open(&dir.0).expect("open");
    assert!(data.load_stereo(1).is_ok());
    assert!(data.load(2).is_ok());
    assert!(matches!(
        data.load_stereo(2),
        Err(DatasetError::Frame {
            index: 2,
            source: FrameError::RightSize {
                image: (12, 5),
                right: (11, 5)
            }
        })
    ));
}

// ---------------------------------------------------------------- EuRoC

fn sensor_yaml(t_bs: &Isometry3<f64>, intrinsics: &str) -> String {
    let m = t_bs.to_homogeneous();
    let rows: Vec<String> = (0..4)
        .map(|r| {
            (0..4)
                .map(|c| format!("{:.17e}", m[(r, c)]))
                .collect::<Vec<_>>()
                .join(", ")
        })
        .collect();
    format!(
        "sensor_type: camera\nT_BS:\n  cols: 4\n  rows: 4\n  data: [{}]\nresolution: [10, 6]\n\
         camera_model: pinhole\nintrinsics: [{intrinsics}]\ndistortion_model: radial-tangential\n\
         distortion_coefficients: [-0.28, 0.07, 0.0002, 1.7e-05]\n",
        rows.join(",\n         ")
    )
}

/// Two cameras about 11 cm apart on a body frame with non-trivial `T_BS` each; `cam1` lacks
/// the last `cam0` frame.
fn euroc_stereo(dir: &TempDir) -> (Isometry3<f64>, Isometry3<f64>) {
    let t_bs0 = Isometry3::new(
        Vector3::new(-0.0216, -0.0647, 0.0098),
        Vector3::new(0.02, -0.03, 1.56),
    );
    let t_bs1 = Isometry3::new(
        Vector3::new(-0.0198, 0.0454, 0.0079),
        Vector3::new(0.01, -0.02, 1.55),
    );
    let stamps = [
        "1403636579763555584",
        "1403636579813555456",
        "1403636579863555584",
    ];
    let list = |n: usize| {
        let mut s = String::from("#timestamp [ns],filename\n");
        for stamp in &stamps[..n] {
            s.push_str(&format!("{stamp},{stamp}.png\n"));
        }
        s
    };
    dir.write("mav0/cam0/data.csv", &list(3));
    dir.write("mav0/cam1/data.csv", &list(2));
    dir.write(
        "mav0/cam0/sensor.yaml",
        &sensor_yaml(&t_bs0, "458.654, 457.296, 367.215, 248.375"),
    );
    dir.write(
        "mav0/cam1/sensor.yaml",
        &sensor_yaml(&t_bs1, "457.587, 456.134, 379.999, 255.238"),
    );
    for (i, stamp) in stamps.iter().enumerate() {
        dir.grey_png(
            &format!("mav0/cam0/data/{stamp}.png"),
            (10, 6),
            20 + i as u8,
        );
        dir.grey_png(
            &format!("mav0/cam1/data/{stamp}.png"),
            (10, 6),
            120 + i as u8,
        );
    }
    (t_bs0, t_bs1)
}

#[test]
fn euroc_cam1_gives_the_right_images_by_timestamp_and_the_stereo_rig() {
    let dir = TempDir::new("euroc");
    let (t_bs0, t_bs1) = euroc_stereo(&dir);
    let data = Dataset::open(&dir.0).expect("open");
    assert_eq!(data.kind, DatasetKind::Euroc);
    assert_eq!(data.len(), 3);
    assert_eq!(
        data.frames[1].right.as_deref(),
        Some(
            dir.0
                .join("mav0/cam1/data/1403636579813555456.png")
                .as_path()
        )
    );
    assert!(
        data.frames[2].right.is_none(),
        "cam1 has no frame at that time"
    );

    let rig = data.rig.expect("rig");
    assert_eq!(rig.left(), &data.camera.expect("camera"));
    assert_eq!(rig.right().expect("right").pinhole.cx, 379.999);
    let same = |a: &Isometry3<f64>, b: &Isometry3<f64>| {
        (a.to_homogeneous() - b.to_homogeneous()).norm() < 1e-12
    };
    assert!(same(&rig.left_in_body().t_bs, &t_bs0));
    assert!(same(&rig.right_in_body().expect("right").t_bs, &t_bs1));
    assert!(same(&data.camera_in_body.expect("T_BS"), &t_bs0));
    // T_RL = T_BS1^-1 T_BS0: the left camera's centre seen from the right camera.
    let t_rl = rig.t_right_left().expect("stereo");
    let centre = t_rl * Point3::origin();
    assert!((centre - t_bs1.inverse() * Point3::from(t_bs0.translation.vector)).norm() < 1e-12);
    let baseline = (t_bs1.translation.vector - t_bs0.translation.vector).norm();
    assert!((rig.baseline().expect("stereo") - baseline).abs() < 1e-12);

    let frame = data.load_stereo(1).expect("stereo frame");
    assert_eq!(frame.image().at(9, 5), 21);
    assert_eq!(frame.right().expect("right").at(0, 0), 121);
    assert!(data.load(1).expect("mono").right().is_none());
    assert!(matches!(
        data.load_stereo(2),
        Err(DatasetError::NoRightImage { index: 2 })
    ));
}

#[test]
fn euroc_cam1_without_calibration_or_with_a_zero_baseline_is_a_typed_error() {
    let dir = TempDir::new("euroc-bad");
    let (t_bs0, _) = euroc_stereo(&dir);
    dir.write(
        "mav0/cam1/sensor.yaml",
        &sensor_yaml(&t_bs0, "457.587, 456.134, 379.999, 255.238"),
    );
    match Dataset::open(&dir.0) {
        Err(DatasetError::Rig {
            path,
            source: RigError::ZeroBaseline { .. },
        }) => assert_eq!(path, dir.0.join("mav0/cam1/sensor.yaml")),
        other => panic!("expected a zero baseline, got {other:?}"),
    }
    fs::remove_file(dir.0.join("mav0/cam1/sensor.yaml")).expect("rm");
    assert!(matches!(
        Dataset::open(&dir.0),
        Err(DatasetError::MissingCalibration { path }) if path.ends_with("cam1/sensor.yaml")
    ));
    // Without cam1 the rig is cam0 alone at its T_BS.
    fs::remove_dir_all(dir.0.join("mav0/cam1")).expect("rm");
    let data = Dataset::open(&dir.0).expect("mono");
    let rig = data.rig.expect("rig");
    assert!(!rig.is_stereo());
    assert!((rig.left_in_body().t_bs.translation.vector - t_bs0.translation.vector).norm() < 1e-12);
}

// ---------------------------------------------------------------- real data

/// `../shared/data/<name>` from the repository root, `None` (with a message) when absent.
fn shared(name: &str) -> Option<PathBuf> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/data")
        .join(name);
    if path.is_dir() {
        Some(path)
    } else {
        eprintln!("skipping: {} is absent", path.display());
        None
    }
}

/// `img` resampled through a rectification map, rounded back to 8 bits.
fn remap(img: &Image<u8>, map: &vofront::core::UndistortMap) -> Image<u8> {
    let remap =
        Remap::new(img.size(), (map.width, map.height), &map.map_x, &map.map_y).expect("remap");
    remap
        .bilinear(&img.to_f32(), 0.0)
        .expect("resample")
        .map(|&v| v.round().clamp(0.0, 255.0) as u8)
}

/// Row offsets `|dy|` (pixels, sorted) of the ORB matches between a left and a right image.
fn row_offsets(orb: &Orb, left: &Image<u8>, right: &Image<u8>) -> Vec<f64> {
    let (l, r) = (
        orb.detect_and_describe(left).expect("orb"),
        orb.detect_and_describe(right).expect("orb"),
    );
    let matches = match_descriptors(l.descriptors(), r.descriptors(), &MatchConfig::default());
    let mut dy: Vec<f64> = matches
        .iter()
        .map(|m| f64::from((l.ys()[m.query as usize] - r.ys()[m.train as usize]).abs()))
        .collect();
    dy.sort_by(f64::total_cmp);
    dy
}

#[test]
fn euroc_real_rig_rectifies_matched_features_onto_the_same_row() {
    let Some(root) = shared("euroc_mh01_stereo60") else {
        return;
    };
    let data = Dataset::open(&root).expect("open EuRoC");
    let rig = data.rig.expect("rig");
    assert!(rig.is_stereo());
    assert!((rig.baseline().expect("stereo") - 0.110).abs() < 0.002);
    let first = data.load_stereo(0).expect("stereo frame");
    let (w, h) = first.image().size();
    let rect = StereoRectification::new(&rig, w, h).expect("rectify");
    let orb = Orb::new(OrbConfig {
        n_features: 1000,
        ..OrbConfig::default()
    })
    .expect("orb");
    let (mut raw, mut rectified) = (Vec::new(), Vec::new());
    for index in [0, 20, 40, 59] {
        let frame = data.load_stereo(index).expect("stereo frame");
        let right = frame.right().expect("right");
        raw.extend(row_offsets(&orb, frame.image(), right));
        let left_r = remap(frame.image(), rect.map_left());
        let right_r = remap(right, rect.map_right());
        rectified.extend(row_offsets(&orb, &left_r, &right_r));
    }
    raw.sort_by(f64::total_cmp);
    rectified.sort_by(f64::total_cmp);
    let median = |v: &[f64]| v[v.len() / 2];
    // ORB keypoints sit on whole pixels of their pyramid level, so also look at the spread.
    let inliers: Vec<f64> = rectified.iter().copied().filter(|&d| d <= 2.0).collect();
    let mean_inlier = inliers.iter().sum::<f64>() / inliers.len() as f64;
    let within_1px =
        rectified.iter().filter(|&&d| d <= 1.0).count() as f64 / rectified.len() as f64;
    eprintln!(
        "EuRoC MH01 (frames 0, 20, 40, 59): median |dy| raw {:.2} px, rectified {:.2} px over \
         {} matches; {:.1}% within 1 px, {:.1}% within 2 px (mean |dy| {:.3} px); pinhole {:?}, \
         baseline {:.4} m",
        median(&raw),
        median(&rectified),
        rectified.len(),
        100.0 * within_1px,
        100.0 * inliers.len() as f64 / rectified.len() as f64,
        mean_inlier,
        rect.pinhole(),
        rect.baseline()
    );
    assert!(rectified.len() > 400, "{} matches", rectified.len());
    assert!(median(&rectified) <= 0.3, "{}", median(&rectified));
    assert!(within_1px > 0.75, "{within_1px}");
    assert!(
        median(&raw) > 5.0,
        "the raw pair is not rectified: {}",
        median(&raw)
    );
}

#[test]
fn kitti_real_rig_is_already_rectified() {
    let Some(root) = shared("kitti_06") else {
        return;
    };
    let data = Dataset::open(&root).expect("open KITTI");
    let rig = data.rig.expect("rig");
    assert!((rig.baseline().expect("stereo") - 0.537).abs() < 0.001);
    let frame = data.load_stereo(0).expect("stereo frame");
    let (w, h) = frame.image().size();
    assert_eq!(frame.right().expect("right").size(), (w, h));
    let rect = StereoRectification::new(&rig, w, h).expect("rectify");
    assert_eq!(*rect.rotation_left(), Rotation3::identity());
    assert_eq!(*rect.rotation_right(), Rotation3::identity());
    let (p, want) = (rect.pinhole(), rig.left().pinhole);
    assert!((p.fx - want.fx).abs() < 1e-9 && (p.cx - want.cx).abs() < 1e-9);
    assert!((p.fy - want.fy).abs() < 1e-9 && (p.cy - want.cy).abs() < 1e-9);
}
