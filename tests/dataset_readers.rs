//! Dataset readers (TUM RGB-D, KITTI, EuRoC, image folders) on small hand-written folders,
//! the camera each dataset names, and the
//! trajectory text formats and timestamp association.

use std::fs;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use image::{GrayImage, ImageBuffer, Luma, Rgb, RgbImage};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use proptest::prelude::*;
use vofront::dataset::tum::tum_preset_for;
use vofront::dataset::{CameraSource, Dataset, DatasetConfig, DatasetError, DatasetKind};
use vofront::fixtures::scene::{default_camera, room_trajectory, Scene};
use vofront::fixtures::tum::write_tum_sequence;
use vofront::trajectory::{associate, associate_stamps, Trajectory, TrajectoryError};

/// Depth PNG quantisation of TUM: one unit is 1/5000 m, so rounding errs by half of it.
const TUM_DEPTH_QUANTUM: f32 = 1.0 / 5000.0;
/// TUM text keeps 9 decimals of positions and quaternion components.
const TEXT_VALUE_TOLERANCE: f64 = 2e-9;

/// A fresh folder under the system temp dir, removed on drop.
struct TempDir(PathBuf);

impl TempDir {
    fn new(tag: &str) -> Self {
        static COUNTER: AtomicUsize = AtomicUsize::new(0);
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let dir = std::env::temp_dir().join(format!("vofront-ds-{tag}-{}-{n}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).expect("temp dir");
        Self(dir)
    }

    fn write(&self, rel: &str, text: &str) -> PathBuf {
        let path = self.0.join(rel);
        fs::create_dir_all(path.parent().expect("has parent")).expect("mkdir");
        fs::write(&path, text).expect("write");
        path
    }

    fn grey_png(&self, rel: &str, value: u8) {
        let path = self.0.join(rel);
        fs::create_dir_all(path.parent().expect("has parent")).expect("mkdir");
        GrayImage::from_pixel(8, 6, Luma([value]))
            .save(path)
            .expect("png");
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = fs::remove_dir_all(&self.0);
    }
}

// ---------------------------------------------------------------- TUM RGB-D

#[test]
fn tum_rendered_sequence_round_trips_images_depth_and_ground_truth() {
    let dir = TempDir::new("tum-rendered");
    let poses = room_trajectory(4);
    let (w, h) = (48, 36);
    let scene = Scene::box_room(3);
    let camera = default_camera();
    write_tum_sequence(&dir.0, &scene, &camera, (w, h), &poses).expect("write fixture");

    let data = Dataset::open(&dir.0).expect("open");
    assert_eq!(data.kind, DatasetKind::Tum);
    assert_eq!(data.len(), 4);
    assert!(data.camera.is_none());
    assert_eq!(data.depth_scale, Some(5000.0));
    for (i, frame) in data.iter() {
        let frame = frame.expect("frame loads");
        let view = scene.render(&camera, w, h, &poses[i]);
        // RGB(g, g, g) must convert back to g exactly.
        let want = vofront::fixtures::image2d::to_gray8(&view.image);
        assert_eq!(frame.image(), &want, "frame {i}");
        let depth = frame.depth().expect("depth associated");
        for (a, b) in depth.data().iter().zip(view.depth.data()) {
            assert!((a - b).abs() <= TUM_DEPTH_QUANTUM * 0.5 + 1e-6);
        }
        let gt = data
            .ground_truth_at(i)
            .expect("ground truth within tolerance");
        assert!(
            (gt.translation.vector - poses[i].translation.vector).norm()
                < TEXT_VALUE_TOLERANCE * 4.0
        );
    }
}

#[test]
fn tum_association_respects_the_tolerance() {
    let dir = TempDir::new("tum-assoc");
    dir.write(
        "rgb.txt",
        "# timestamp filename\n10.000 rgb/a.png\n10.100 rgb/b.png\n10.200 rgb/c.png\n",
    );
    // a: depth 15 ms later (kept), b: 25 ms (beyond 20 ms), c: 5 ms earlier.
    dir.write(
        "depth.txt",
        "10.015 depth/a.png\n10.125 depth/b.png\n10.195 depth/c.png\n",
    );
    dir.write(
        "groundtruth.txt",
        "10.01 1 2 3 0 0 0 1\n10.13 4 5 6 0 0 0 1\n10.2 7 8 9 0 0 0 2\n",
    );
    let rgb = RgbImage::from_fn(8, 6, |x, _| Rgb([x as u8 * 30, 0, 0]));
    fs::create_dir_all(dir.0.join("rgb")).expect("mkdir");
    fs::create_dir_all(dir.0.join("depth")).expect("mkdir");
    for name in ["a", "b", "c"] {
        rgb.save(dir.0.join(format!("rgb/{name}.png")))
            .expect("png");
        let depth: ImageBuffer<Luma<u16>, Vec<u16>> =
            ImageBuffer::from_fn(8, 6, |x, _| Luma([x as u16 * 2500]));
        depth
            .save(dir.0.join(format!("depth/{name}.png")))
            .expect("png");
    }
    let data = Dataset::open(&dir.0).expect("open");
    let depth_names: Vec<Option<PathBuf>> = data.frames.iter().map(|f| f.depth.clone()).collect();
    assert_eq!(
        depth_names,
        vec![
            Some(dir.0.join("depth/a.png")),
            None,
            Some(dir.0.join("depth/c.png"))
        ]
    );
    let frame = data.load(0).expect("frame 0");
    let depth = frame.depth().expect("depth");
    assert_eq!(depth.at(0, 0), 0.0, "0 stays invalid");
    assert_eq!(depth.at(3, 2), 1.5, "3 * 2500 / 5000 m");
    // Colour is converted: a red-only image gives a darker grey that grows with red.
    assert!(frame.image().at(7, 0) > frame.image().at(1, 0));
    assert!(data.load(1).expect("frame 1").depth().is_none());
    // Ground truth: nearest stamp within 20 ms; frame 1 (10.1) is 30 ms from 10.13.
    let gt0 = data.ground_truth_at(0).expect("gt 0");
    assert_eq!(gt0.translation.vector, Vector3::new(1.0, 2.0, 3.0));
    assert!(data.ground_truth_at(1).is_none());
    let gt2 = data.ground_truth_at(2).expect("gt 2");
    assert!(
        gt2.rotation.angle() < 1e-12,
        "quaternion (0,0,0,2) normalised"
    );
}

#[test]
fn missing_or_corrupt_frames_fail_alone() {
    let dir = TempDir::new("tum-missing");
    dir.write(
        "rgb.txt",
        "1.0 rgb/0.png\n2.0 rgb/1.png\n3.0 rgb/2.png\n4.0 rgb/3.png\n",
    );
    dir.grey_png("rgb/0.png", 10);
    dir.write("rgb/2.png", "not a png at all");
    dir.grey_png("rgb/3.png", 30);
    let data = Dataset::open(&dir.0).expect("open");
    let results: Vec<_> = data.iter().collect();
    assert_eq!(results.len(), 4);
    assert_eq!(results[0].1.as_ref().expect("0 loads").image().at(0, 0), 10);
    assert!(matches!(
        results[1].1,
        Err(DatasetError::Image { index: 1, .. })
    ));
    assert!(matches!(
        results[2].1,
        Err(DatasetError::Image { index: 2, .. })
    ));
    assert_eq!(results[3].1.as_ref().expect("3 loads").image().at(0, 0), 30);
    assert!(matches!(
        data.load(4),
        Err(DatasetError::FrameIndex { index: 4, len: 4 })
    ));
}

#[test]
fn unparsable_lines_name_file_and_line() {
    let dir = TempDir::new("tum-parse");
    let rgb = dir.write("rgb.txt", "# header\n1.0 rgb/0.png\nbanana rgb/1.png\n");
    match Dataset::open(&dir.0) {
        Err(DatasetError::Parse { path, line, .. }) => {
            assert_eq!((path, line), (rgb, 3));
        }
        other => panic!("expected a parse error, got {other:?}"),
    }
    dir.write("rgb.txt", "1.0 rgb/0.png\n");
    let gt = dir.write("groundtruth.txt", "1.0 0 0 0 0 0 0 1\n1.1 0 0 0 0 0 1\n");
    match Dataset::open(&dir.0) {
        Err(DatasetError::Trajectory(TrajectoryError::Parse { path, line, .. })) => {
            assert_eq!((path, line), (gt, 2));
        }
        other => panic!("expected a ground-truth parse error, got {other:?}"),
    }
}

#[test]
fn empty_and_unknown_folders_are_typed_errors() {
    let dir = TempDir::new("empty");
    assert!(matches!(Dataset::open(&dir.0), Err(DatasetError::Empty(_))));
    assert!(matches!(
        Dataset::open(dir.0.join("does-not-exist")),
        Err(DatasetError::Empty(_))
    ));
    dir.write("notes.txt", "hello");
    assert!(matches!(
        Dataset::open(&dir.0),
        Err(DatasetError::Unrecognised(_))
    ));
    dir.write("rgb.txt", "# no frames\n");
    assert!(matches!(
        Dataset::open(&dir.0),
        Err(DatasetError::NoFrames(_))
    ));
}

#[test]
fn tum_presets_follow_the_folder_name() {
    let fr1 = tum_preset_for(Path::new("/data/rgbd_dataset_freiburg1_xyz")).expect("fr1");
    assert_eq!(fr1.pinhole.fx, 517.3);
    assert_eq!(fr1.distortion.coefficients()[4], 1.1633);
    let fr3 = tum_preset_for(Path::new("rgbd_dataset_freiburg3_long_office")).expect("fr3");
    assert!(fr3.distortion.is_identity());
    assert!(tum_preset_for(Path::new("/data/my_sequence")).is_none());
}

#[test]
fn tum_camera_comes_from_the_folder_name_or_the_list_header() {
    let dir = TempDir::new("tum-cam");
    let named = dir.0.join("rgbd_dataset_freiburg2_desk");
    fs::create_dir_all(&named).expect("mkdir");
    fs::write(named.join("rgb.txt"), "1.0 rgb/a.png\n").expect("rgb");
    let data = Dataset::open(&named).expect("open");
    assert_eq!(data.camera.expect("fr2").pinhole.fx, 520.9);
    assert_eq!(
        data.camera_source,
        Some(CameraSource::FolderName("freiburg2".into()))
    );
    // A renamed folder: the benchmark's list header still names the sequence.
    let plain = dir.0.join("my_copy");
    fs::create_dir_all(&plain).expect("mkdir");
    let rgb = plain.join("rgb.txt");
    fs::write(
        &rgb,
        "# color images\n# file: 'rgbd_dataset_freiburg1_xyz.bag'\n# timestamp filename\n1.0 rgb/a.png\n",
    )
    .expect("rgb");
    let data = Dataset::open(&plain).expect("open");
    assert_eq!(
        data.camera.expect("fr1").distortion.coefficients()[4],
        1.1633
    );
    assert_eq!(
        data.camera_source,
        Some(CameraSource::FileHeader(rgb.clone()))
    );
    // Nothing names the camera: none is invented.
    fs::write(&rgb, "# timestamp filename\n1.0 rgb/a.png\n").expect("rgb");
    let data = Dataset::open(&plain).expect("open");
    assert!(data.camera.is_none() && data.camera_source.is_none());
}

// ---------------------------------------------------------------- image folders

#[test]
fn image_folders_are_timed_by_fps_or_by_file_names() {
    let dir = TempDir::new("images");
    for (name, v) in [("000002.png", 20), ("000000.png", 0), ("000001.jpg", 10)] {
        dir.grey_png(name, v);
    }
    dir.write("notes.txt", "not an image");
    // Frame numbers are no timestamps.
    assert!(matches!(
        Dataset::open(&dir.0),
        Err(DatasetError::Parse { .. })
    ));
    let cfg = DatasetConfig {
        fps: Some(10.0),
        ..DatasetConfig::default()
    };
    let data = Dataset::open_with(&dir.0, &cfg).expect("open with fps");
    assert_eq!(data.kind, DatasetKind::Images);
    let times: Vec<f64> = data.frames.iter().map(|f| f.timestamp).collect();
    assert_eq!(times, vec![0.0, 0.1, 0.2]);
    assert_eq!(data.load(2).expect("frame 2").image().at(1, 1), 20);
    assert!(data.camera.is_none() && data.ground_truth.is_none());

    let stamped = TempDir::new("images-stamped");
    stamped.grey_png("1305031102.275304.png", 5);
    stamped.grey_png("1305031102.175304.png", 4);
    let data = Dataset::open(&stamped.0).expect("open stamped");
    assert_eq!(data.frames[0].timestamp, 1305031102.175304);
    assert_eq!(data.load(1).expect("frame 1").image().at(0, 0), 5);
    let bad = DatasetConfig {
        fps: Some(-5.0),
        ..DatasetConfig::default()
    };
    assert!(Dataset::open_with(&stamped.0, &bad).is_err());
}

// ---------------------------------------------------------------- KITTI

const KITTI_CALIB: &str = "P0: 7.188560000000e+02 0.000000000000e+00 6.071928000000e+02 0.000000000000e+00 0.000000000000e+00 7.188560000000e+02 1.852157000000e+02 0.000000000000e+00 0.000000000000e+00 0.000000000000e+00 1.000000000000e+00 0.000000000000e+00
P1: 7.188560000000e+02 0.000000000000e+00 6.071928000000e+02 -3.861448000000e+02 0.000000000000e+00 7.188560000000e+02 1.852157000000e+02 0.000000000000e+00 0.000000000000e+00 0.000000000000e+00 1.000000000000e+00 0.000000000000e+00
";

fn kitti_sequence(dir: &Path) {
    fs::create_dir_all(dir.join("image_0")).expect("mkdir");
    fs::write(dir.join("calib.txt"), KITTI_CALIB).expect("calib");
    fs::write(
        dir.join("times.txt"),
        "0.000000e+00\n1.036000e-01\n2.072000e-01\n",
    )
    .expect("times");
    for i in [0u8, 2] {
        GrayImage::from_pixel(10, 4, Luma([i * 50]))
            .save(dir.join(format!("image_0/{i:06}.png")))
            .expect("png");
    }
    // Listed (one image per timestamp) but corrupt: that frame alone fails to load.
    fs::write(dir.join("image_0/000001.png"), "not a png").expect("corrupt png");
}

const KITTI_POSES: &str = "1 0 0 0 0 1 0 0 0 0 1 0
1.000000e+00 0 0 1.5e-01 0 1 0 -2.0e-02 0 0 1 8.5e-01
0 -1 0 1 1 0 0 2 0 0 1 3
";

#[test]
fn kitti_reads_calibration_times_images_and_poses() {
    let dir = TempDir::new("kitti");
    let seq = dir.0.join("dataset/sequences/05");
    kitti_sequence(&seq);
    fs::create_dir_all(dir.0.join("dataset/poses")).expect("mkdir");
    fs::write(dir.0.join("dataset/poses/05.txt"), KITTI_POSES).expect("poses");

    let data = Dataset::open(&seq).expect("open");
    assert_eq!(data.kind, DatasetKind::Kitti);
    assert_eq!(
        data.camera_source,
        Some(CameraSource::CalibrationFile(seq.join("calib.txt")))
    );
    let cam = data.camera.expect("camera from P0");
    assert_eq!(
        (
            cam.pinhole.fx,
            cam.pinhole.fy,
            cam.pinhole.cx,
            cam.pinhole.cy
        ),
        (718.856, 718.856, 607.1928, 185.2157)
    );
    assert!(cam.distortion.is_identity());
    assert_eq!(data.frames[1].timestamp, 0.1036);
    assert_eq!(data.load(2).expect("frame 2").image().at(0, 0), 100);
    assert!(matches!(
        data.load(1),
        Err(DatasetError::Image { index: 1, .. })
    ));
    let gt = data
        .ground_truth
        .as_ref()
        .expect("poses found in ../../poses");
    assert_eq!(gt.len(), 3);
    assert_eq!(gt.poses[1].0, 0.1036);
    assert_eq!(
        gt.poses[1].1.translation.vector,
        Vector3::new(0.15, -0.02, 0.85)
    );
    // Row-major [R | t]: third pose rotates x onto y (90 deg about z).
    let r = gt.poses[2].1.rotation * Vector3::x();
    assert!((r - Vector3::y()).norm() < 1e-12);
    assert_eq!(
        data.ground_truth_at(2).expect("gt").translation.vector,
        Vector3::new(1.0, 2.0, 3.0)
    );
}

#[test]
fn kitti_poses_txt_in_the_folder_and_missing_calibration() {
    let dir = TempDir::new("kitti-local");
    kitti_sequence(&dir.0);
    dir.write("poses.txt", KITTI_POSES);
    let data = Dataset::open(&dir.0).expect("open");
    assert_eq!(data.ground_truth.expect("poses.txt").len(), 3);

    dir.write("poses.txt", "1 0 0 0 0 1 0 0 0 0 1 0\n");
    assert!(matches!(
        Dataset::open(&dir.0),
        Err(DatasetError::Trajectory(TrajectoryError::CountMismatch {
            poses: 1,
            times: 3
        }))
    ));
    fs::remove_file(dir.0.join("calib.txt")).expect("rm");
    match Dataset::open(&dir.0) {
        Err(DatasetError::MissingCalibration { path }) => assert_eq!(path, dir.0.join("calib.txt")),
        other => panic!("expected missing calibration, got {other:?}"),
    }
}

// ---------------------------------------------------------------- EuRoC

const EUROC_SENSOR: &str = "# General sensor definitions.
sensor_type: camera
comment: VI-Sensor cam0 (MT9M034)

# Sensor extrinsics wrt. the body-frame.
T_BS:
  cols: 4
  rows: 4
  data: [0.0148655429818, -0.999880929698, 0.00414029679422, -0.0216401454975,
         0.999557249008, 0.0149672133247, 0.025715529948, -0.064676986768,
        -0.0257744366974, 0.00375618835797, 0.999660727178, 0.00981073058949,
         0.0, 0.0, 0.0, 1.0]

# Camera specific definitions.
rate_hz: 20
resolution: [752, 480]
camera_model: pinhole
intrinsics: [458.654, 457.296, 367.215, 248.375] #fu, fv, cu, cv
distortion_model: radial-tangential
distortion_coefficients: [-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05]
";

fn euroc_folder(dir: &TempDir) {
    dir.write(
        "mav0/cam0/data.csv",
        "#timestamp [ns],filename\n1403636579763555584,1403636579763555584.png\n1403636579813555456,1403636579813555456.png\n",
    );
    dir.grey_png("mav0/cam0/data/1403636579763555584.png", 77);
    dir.grey_png("mav0/cam0/data/1403636579813555456.png", 88);
    dir.write("mav0/cam0/sensor.yaml", EUROC_SENSOR);
}

#[test]
fn euroc_reads_camera_nanosecond_stamps_and_body_ground_truth() {
    let dir = TempDir::new("euroc");
    euroc_folder(&dir);
    dir.write(
        "mav0/state_groundtruth_estimate0/data.csv",
        "#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], q_RS_y [], q_RS_z [], v_RS_R_x [m s^-1], v_RS_R_y [m s^-1], v_RS_R_z [m s^-1], b_w_RS_S_x [rad s^-1], b_w_RS_S_y [rad s^-1], b_w_RS_S_z [rad s^-1], b_a_RS_S_x [m s^-2], b_a_RS_S_y [m s^-2], b_a_RS_S_z [m s^-2]\n\
1403636579758555392,4.688319,-1.786938,0.783338,0.534108,-0.153029,-0.827383,-0.082152,-0.027876,0.033207,0.800006,-0.003172,0.021267,0.078502,-0.025266,0.136696,0.075593\n",
    );
    let data = Dataset::open(&dir.0).expect("open");
    assert_eq!(data.kind, DatasetKind::Euroc);
    let cam = data.camera.expect("camera");
    assert_eq!(
        (
            cam.pinhole.fx,
            cam.pinhole.fy,
            cam.pinhole.cx,
            cam.pinhole.cy
        ),
        (458.654, 457.296, 367.215, 248.375)
    );
    assert_eq!(
        cam.distortion.coefficients(),
        [-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05, 0.0]
    );
    assert!((data.frames[0].timestamp - 1403636579.0 - 0.763555584).abs() < 1e-6);
    assert!((data.frames[1].timestamp - data.frames[0].timestamp - 0.049999872).abs() < 1e-6);
    assert_eq!(data.load(1).expect("frame 1").image().at(3, 3), 88);
    // Body pose 5 ms before frame 0: found within the 20 ms tolerance, quaternion w first.
    let body = data.ground_truth_at(0).expect("gt");
    assert_eq!(
        body.translation.vector,
        Vector3::new(4.688319, -1.786938, 0.783338)
    );
    let q = UnitQuaternion::new_normalize(nalgebra::Quaternion::new(
        0.534108, -0.153029, -0.827383, -0.082152,
    ));
    assert!(body.rotation.angle_to(&q) < 1e-12);
    assert!(data.ground_truth_at(1).is_none(), "55 ms away");
    // T_BS: row-major 4x4 over several lines; its first column is the camera x axis in the body.
    let t_bc = data.camera_in_body.expect("T_BS");
    assert_eq!(
        t_bc.translation.vector,
        Vector3::new(-0.0216401454975, -0.064676986768, 0.00981073058949)
    );
    let x_axis = t_bc.rotation * Vector3::x();
    let want = Vector3::new(0.0148655429818, 0.999557249008, -0.0257744366974);
    assert!((x_axis - want).norm() < 1e-5, "{x_axis:?}");
}

/// OpenCV writes `%YAML:1.0` and `!!opencv-matrix`, which YAML parsers reject; both are
/// tolerated.
#[test]
fn euroc_sensor_yaml_written_by_opencv_is_read() {
    let dir = TempDir::new("euroc-opencv");
    euroc_folder(&dir);
    let opencv = format!(
        "%YAML:1.0\n{}",
        EUROC_SENSOR.replace("T_BS:\n", "T_BS: !!opencv-matrix\n")
    );
    let sensor = dir.write("mav0/cam0/sensor.yaml", &opencv);
    let data = Dataset::open(&dir.0).expect("open");
    assert_eq!(data.camera.expect("camera").pinhole.cx, 367.215);
    assert_eq!(
        data.camera_in_body.expect("T_BS").translation.vector.z,
        0.00981073058949
    );
    assert_eq!(
        data.camera_source,
        Some(CameraSource::CalibrationFile(sensor))
    );
    dir.write(
        "mav0/cam0/sensor.yaml",
        &EUROC_SENSOR.replace("radial-tangential", "double-sphere"),
    );
    assert!(matches!(
        Dataset::open(&dir.0),
        Err(DatasetError::Parse { .. })
    ));
}

#[test]
fn euroc_missing_calibration_is_a_typed_error() {
    let dir = TempDir::new("euroc-nocalib");
    euroc_folder(&dir);
    fs::remove_file(dir.0.join("mav0/cam0/sensor.yaml")).expect("rm");
    assert!(matches!(
        Dataset::open(&dir.0),
        Err(DatasetError::MissingCalibration { .. })
    ));
    dir.write(
        "mav0/cam0/sensor.yaml",
        "intrinsics: [458.654, 457.296, 367.215]\n",
    );
    assert!(matches!(
        Dataset::open(&dir.0),
        Err(DatasetError::Parse { line: 1, .. })
    ));
}

// ---------------------------------------------------------------- trajectories

#[test]
fn tum_text_tolerates_commas_comments_and_blank_lines() {
    let t = Trajectory::from_tum_str(
        "# t x y z qx qy qz qw\n\n1.5,1,2,3,0,0,0,1\n  2.5 4 5 6 0 0 1 0  \n",
    )
    .expect("parse");
    assert_eq!(t.timestamps(), vec![1.5, 2.5]);
    assert_eq!(t.poses[1].1.translation.vector, Vector3::new(4.0, 5.0, 6.0));
    assert!((t.poses[1].1.rotation.angle() - std::f64::consts::PI).abs() < 1e-12);
    assert!(matches!(
        Trajectory::from_tum_str("1 2 3\n"),
        Err(TrajectoryError::Parse { line: 1, .. })
    ));
    assert!(matches!(
        Trajectory::from_tum_str("1 0 0 0 0 0 0 0\n"),
        Err(TrajectoryError::Parse { line: 1, .. })
    ));
}

#[test]
fn association_is_nearest_within_tolerance_and_one_to_one() {
    let a = [0.0, 0.1, 0.2, 0.3, 0.4];
    let b = [0.005, 0.104, 0.23, 0.395, 0.41];
    // 0.2 and 0.3 have nothing within 10 ms; 0.4 takes 0.395 (5 ms) over 0.41 (10 ms).
    // Equal lengths: evo iterates over the second list, so pairs come in its order.
    assert_eq!(associate_stamps(&a, &b, 0.01), vec![(0, 0), (1, 1), (4, 3)]);
    // Two stamps of `a` closest to the same stamp of `b`: only the closer pair is kept.
    assert_eq!(
        associate_stamps(&[1.0, 1.004], &[1.003, 2.0, 3.0], 0.01),
        vec![(1, 0)]
    );
    // Unsorted stamps fall back to a linear search.
    assert_eq!(
        associate_stamps(&[0.3, 0.1], &[0.1, 0.2, 0.3], 0.01),
        vec![(0, 2), (1, 0)]
    );
    let ta = Trajectory::new(a.iter().map(|&t| (t, Isometry3::identity())).collect());
    let tb = Trajectory::new(b.iter().map(|&t| (t, Isometry3::identity())).collect());
    assert_eq!(associate(&ta, &tb, 0.01), associate_stamps(&a, &b, 0.01));
}

fn pose_strategy() -> impl Strategy<Value = (f64, Isometry3<f64>)> {
    (
        0.0f64..2e9,
        prop::array::uniform3(-1e3f64..1e3),
        prop::array::uniform3(-3.0f64..3.0),
    )
        .prop_map(|(t, p, r)| {
            (
                t,
                Isometry3::from_parts(
                    Translation3::new(p[0], p[1], p[2]),
                    UnitQuaternion::from_scaled_axis(Vector3::from(r)),
                ),
            )
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(vofront_fixtures::proptest_cases(64)))]

    /// Writing then reading TUM text keeps every timestamp to 0.5 us (plus f64 rounding) and every pose to the
    /// 9 written decimals.
    #[test]
    fn tum_write_read_round_trip(poses in prop::collection::vec(pose_strategy(), 0..20)) {
        let traj = Trajectory::new(poses);
        let back = Trajectory::from_tum_str(&traj.to_tum_string()).expect("parse");
        prop_assert_eq!(back.len(), traj.len());
        for ((t0, p0), (t1, p1)) in traj.poses.iter().zip(&back.poses) {
            prop_assert!((t0 - t1).abs() <= 0.5e-6 + 2.0 * f64::EPSILON * t0.abs());
            prop_assert!((p0.translation.vector - p1.translation.vector).norm() < TEXT_VALUE_TOLERANCE);
            prop_assert!(p0.rotation.angle_to(&p1.rotation) < 1e-8);
        }
    }
}

#[test]
fn write_tum_then_read_tum_file() {
    let dir = TempDir::new("traj-file");
    let traj = Trajectory::new(
        room_trajectory(5)
            .into_iter()
            .enumerate()
            .map(|(i, p)| (100.0 + i as f64 * 0.05, p))
            .collect(),
    );
    let path = dir.0.join("est.txt");
    traj.write_tum(&path).expect("write");
    let back = Trajectory::read_tum(&path).expect("read");
    assert_eq!(back.timestamps(), traj.timestamps());
    assert!(matches!(
        Trajectory::read_tum(&dir.0.join("nope.txt")),
        Err(TrajectoryError::Io { .. })
    ));
}

/// TUM-VI and RealSense T265 calibrations (Kalibr's `equidistant`) open as a Kannala-Brandt
/// camera with the four coefficients in their order.
#[test]
fn euroc_equidistant_sensor_yaml_opens_as_kannala_brandt() {
    let dir = TempDir::new("euroc-equidistant");
    euroc_folder(&dir);
    dir.write(
        "mav0/cam0/sensor.yaml",
        &EUROC_SENSOR.replace("radial-tangential", "equidistant"),
    );
    let cam = Dataset::open(&dir.0).expect("open").camera.expect("camera");
    assert_eq!(cam.distortion.model_name(), "equidistant");
    assert!(cam.distortion.radial_tangential().is_none());
    assert_eq!(
        cam.distortion.coefficients(),
        [-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05]
    );
    assert_eq!(cam.pinhole.fx, 458.654);
}
