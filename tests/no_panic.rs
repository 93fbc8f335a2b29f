//! Bad input at every public entry point gives `Ok` or a typed `Err`, never a panic: arbitrary
//! sizes, NaN and infinities, empty and mismatched buffers, random bytes as image files and
//! random text as CSV / TUM / KITTI / EuRoC files. Case counts stay small (CI time).

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Matrix3, Point3, Translation3, UnitQuaternion, Vector2, Vector3};
use proptest::prelude::*;
use vofront::dataset::{Dataset, Frame};
use vofront::direct::{
    align_affine, align_homography, align_se3, align_translation, good_features_to_track,
    photometric_residual_map, track_klt, KltConfig, RgbdFrame, Se3Config, TranslationConfig,
    WarpConfig,
};
use vofront::eval::{ate, rpe, Alignment, EvalConfig};
use vofront::features::{
    match_descriptors, match_windowed, Descriptor, Features, MatchConfig, Orb, OrbConfig,
};
use vofront::geometry::essential::{decompose_essential, essential_5pt, essential_8pt};
use vofront::geometry::homography::{decompose_homography, homography_dlt};
use vofront::geometry::{
    bundle_adjust, estimate_relative_pose, solve_pnp_ransac, triangulate_dlt, triangulate_midpoint,
    BundleConfig, BundleProblem, Camera, Distortion, KannalaBrandt, Lens, Observation, Pinhole,
    PnpConfig, RelativePoseConfig, UndistortMap,
};
use vofront::image::Image;
use vofront::input::{load_correspondences, load_depth, load_gray};
use vofront::odometry::direct::{DirectTracker, DirectTrackerConfig};
use vofront::odometry::feature_rgbd::{FeatureRgbdConfig, FeatureRgbdTracker};
use vofront::odometry::mono::{MonoConfig, MonoTracker};
use vofront::odometry::Tracker;
use vofront::pipeline::TwoViewEstimator;
use vofront::trajectory::Trajectory;

/// Runs `f`, failing the property (with `what`) if it panics.
fn no_panic<T>(what: &str, f: impl FnOnce() -> T) -> Result<(), TestCaseError> {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(_) => Ok(()),
        Err(e) => {
            let msg = e
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| e.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_default();
            Err(TestCaseError::fail(format!("{what} panicked: {msg}")))
        }
    }
}

/// Any `f32`, with NaN, infinities and extremes over-represented.
fn wild_f32() -> impl Strategy<Value = f32> {
    prop_oneof![
        4 => -300.0f32..300.0,
        1 => Just(f32::NAN),
        1 => Just(f32::INFINITY),
        1 => Just(f32::NEG_INFINITY),
        1 => any::<f32>(),
    ]
}

/// Any `f64`, with NaN, infinities and extremes over-represented.
fn wild_f64() -> impl Strategy<Value = f64> {
    prop_oneof![
        4 => -1000.0f64..1000.0,
        1 => Just(f64::NAN),
        1 => Just(f64::INFINITY),
        1 => Just(0.0),
        1 => any::<f64>(),
    ]
}

/// A float image of arbitrary (small) size: smooth texture, constant, or wild values.
fn plane() -> impl Strategy<Value = Image<f32>> {
    (0usize..80, 0usize..60, 0u8..3, any::<u64>(), wild_f32()).prop_map(|(w, h, kind, seed, v)| {
        let data = (0..w * h)
            .map(|i| match kind {
                0 => ((i as f32 * 0.37 + seed as f32).sin() * 60.0 + 128.0).floor(),
                1 => v,
                _ => {
                    if (i as u64 ^ seed).is_multiple_of(7) {
                        v
                    } else {
                        (i % 251) as f32
                    }
                }
            })
            .collect();
        Image::new(w, h, data).expect("w * h values")
    })
}

/// A grey image of arbitrary (small) size with random content.
fn gray() -> impl Strategy<Value = Image<u8>> {
    (0usize..120, 0usize..90, any::<u64>()).prop_map(|(w, h, seed)| {
        let data = (0..w * h)
            .map(|i| (((i % w) as u64 * 31 + (i / w) as u64 * 17 + seed) % 256) as u8)
            .collect();
        Image::new(w, h, data).expect("w * h values")
    })
}

/// Points with wild coordinates.
fn points2(max: usize) -> impl Strategy<Value = Vec<Vector2<f64>>> {
    prop::collection::vec(
        (wild_f64(), wild_f64()).prop_map(|(x, y)| Vector2::new(x, y)),
        0..max,
    )
}

fn camera() -> Camera {
    Camera::pinhole(Pinhole::new(520.0, 520.0, 40.0, 30.0).expect("valid intrinsics"))
}

/// A camera whose intrinsics may be wild (validated by the entry points).
fn wild_camera() -> impl Strategy<Value = Camera> {
    (wild_f64(), wild_f64(), wild_f64(), wild_f64())
        .prop_map(|(fx, fy, cx, cy)| Camera::pinhole(Pinhole { fx, fy, cx, cy }))
}

/// A fresh temp folder for one case.
fn temp_dir(tag: &str) -> PathBuf {
    use std::sync::atomic::{AtomicUsize, Ordering};
    static N: AtomicUsize = AtomicUsize::new(0);
    let dir = std::env::temp_dir().join(format!(
        "vofront-no-panic-{tag}-{}-{}",
        std::process::id(),
        N.fetch_add(1, Ordering::Relaxed)
    ));
    std::fs::create_dir_all(&dir).expect("temp dir");
    dir
}

fn write(dir: &Path, name: &str, bytes: &[u8]) {
    let path = dir.join(name);
    if let Some(parent) = path.parent() {
        std::fs::create_dir_all(parent).expect("parent dir");
    }
    std::fs::write(path, bytes).expect("write file");
}

/// Text made of the tokens of the dataset and trajectory formats, shuffled at random.
fn format_text() -> impl Strategy<Value = String> {
    let token = prop_oneof![
        Just("1.0".to_string()),
        Just("-3e300".to_string()),
        Just("nan".to_string()),
        Just("inf".to_string()),
        Just("0".to_string()),
        Just("rgb/a.png".to_string()),
        Just("image_0/000000.png".to_string()),
        Just("P0:".to_string()),
        Just("#".to_string()),
        Just(",".to_string()),
        Just(" ".to_string()),
        Just("\n".to_string()),
        Just("1403636579763555584".to_string()),
        Just("a.png".to_string()),
        "[ -~]{0,12}",
    ];
    prop::collection::vec(token, 0..60).prop_map(|t| t.concat())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(vofront_fixtures::proptest_cases(24)))]

    #[test]
    fn decoders_and_parsers_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..400), text in format_text()) {
        let dir = temp_dir("files");
        write(&dir, "a.png", &bytes);
        write(&dir, "t.txt", text.as_bytes());
        no_panic("load_gray", || load_gray(&dir.join("a.png")))?;
        no_panic("load_depth", || load_depth(&dir.join("a.png"), 5000.0))?;
        no_panic("load_depth scale 0", || load_depth(&dir.join("a.png"), 0.0))?;
        no_panic("load_correspondences", || load_correspondences(&dir.join("t.txt")))?;
        no_panic("from_tum_str", || Trajectory::from_tum_str(&text))?;
        no_panic("read_kitti", || Trajectory::read_kitti(&dir.join("t.txt"), Some(&dir.join("t.txt"))))?;
        no_panic("read_kitti missing", || Trajectory::read_kitti(&dir.join("none.txt"), None))?;
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn dataset_openers_never_panic(text in format_text(), bytes in prop::collection::vec(any::<u8>(), 0..200), layout in 0u8..3) {
        let dir = temp_dir("dataset");
        match layout {
            0 => {
                write(&dir, "rgb.txt", text.as_bytes());
                write(&dir, "depth.txt", text.as_bytes());
                write(&dir, "groundtruth.txt", text.as_bytes());
                write(&dir, "rgb/a.png", &bytes);
            }
            1 => {
                write(&dir, "times.txt", text.as_bytes());
                write(&dir, "calib.txt", text.as_bytes());
                write(&dir, "poses.txt", text.as_bytes());
                write(&dir, "image_0/000000.png", &bytes);
            }
            _ => {
                write(&dir, "mav0/cam0/data.csv", text.as_bytes());
                write(&dir, "mav0/cam0/sensor.yaml", text.as_bytes());
                write(&dir, "mav0/state_groundtruth_estimate0/data.csv", text.as_bytes());
                write(&dir, "mav0/cam0/data/a.png", &bytes);
            }
        }
        no_panic("Dataset::open", || {
            if let Ok(data) = Dataset::open(&dir) {
                for (i, frame) in data.iter().take(3) {
                    drop(frame);
                        std::hint::black_box(data.ground_truth_at(i));
                }
                drop(data.load(usize::MAX));
            }
        })?;
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn two_view_estimators_never_panic(a in points2(40), b in points2(40), cam in wild_camera(), n in 0usize..12) {
        let cfg = RelativePoseConfig::default();
        no_panic("estimate_relative_pose", || estimate_relative_pose(&a, &b, &cam, &cfg))?;
        no_panic("estimate_relative_pose, good camera", || estimate_relative_pose(&a, &b, &camera(), &cfg))?;
        let same_len = a.len().min(b.len());
        no_panic("estimate_relative_pose, equal lengths", || {
            estimate_relative_pose(&a[..same_len], &b[..same_len], &camera(), &cfg)
        })?;
        no_panic("homography_dlt", || homography_dlt(&a, &b))?;
        let m = |p: &[Vector2<f64>]| Matrix3::from_fn(|r, c| p.get(3 * r + c).map_or(1.0, |v| v.x));
        no_panic("decompose_homography", || decompose_homography(&m(&a)))?;
        no_panic("decompose_essential", || decompose_essential(&m(&b)))?;
        let r1: Vec<Vector3<f64>> = a.iter().take(n).map(|p| p.push(1.0)).collect();
        let r2: Vec<Vector3<f64>> = b.iter().take(n).map(|p| p.push(1.0)).collect();
        no_panic("essential_8pt", || essential_8pt(&r1, &r2, &mut Vec::new()))?;
        if r1.len() >= 5 && r2.len() >= 5 {
            let f = |r: &[Vector3<f64>]| -> [Vector3<f64>; 5] { std::array::from_fn(|k| r[k]) };
            no_panic("essential_5pt", || essential_5pt(&f(&r1), &f(&r2), &mut Vec::new()))?;
        }
        let pose = Isometry3::from_parts(
            Translation3::new(a.first().map_or(0.0, |p| p.x), 0.1, 0.0),
            UnitQuaternion::identity(),
        );
        for (p, q) in r1.iter().zip(&r2) {
            no_panic("triangulate_dlt", || triangulate_dlt(&pose, p, q))?;
            no_panic("triangulate_midpoint", || triangulate_midpoint(&pose, p, q))?;
        }
    }

    #[test]
    fn pnp_never_panics(px in points2(30), world in prop::collection::vec((wild_f64(), wild_f64(), wild_f64()), 0..30), cam in wild_camera(), prior in any::<bool>()) {
        let world: Vec<Point3<f64>> = world.into_iter().map(|(x, y, z)| Point3::new(x, y, z)).collect();
        let prior = prior.then(Isometry3::identity);
        no_panic("solve_pnp_ransac", || solve_pnp_ransac(&world, &px, &cam, prior, &PnpConfig::default()))?;
        let n = world.len().min(px.len());
        no_panic("solve_pnp_ransac, equal lengths", || {
            solve_pnp_ransac(&world[..n], &px[..n], &camera(), prior, &PnpConfig::default())
        })?;
    }

    #[test]
    fn bundle_adjustment_never_panics(
        poses in prop::collection::vec((wild_f64(), wild_f64(), wild_f64()), 0..5),
        points in prop::collection::vec((wild_f64(), wild_f64(), wild_f64()), 0..12),
        observations in prop::collection::vec((0usize..6, 0usize..14, wild_f64(), wild_f64()), 0..40),
        cam in wild_camera(),
        fixed in 0usize..4,
        sigma in wild_f64(),
    ) {
        let mut problem = BundleProblem {
            camera: cam,
            poses: poses.iter().map(|&(x, y, z)| Isometry3::new(Vector3::new(x, y, z), Vector3::new(0.01 * y, 0.0, 0.01 * x))).collect(),
            points: points.iter().map(|&(x, y, z)| Point3::new(x, y, z)).collect(),
            observations: observations.iter().map(|&(pose, point, u, v)| Observation { pose, point, pixel: Vector2::new(u, v), sigma: 1.0, right: (point % 2 == 0).then_some(u - v) }).collect(),
            baseline: Some(sigma),
        };
        let cfg = BundleConfig { fixed_poses: fixed, sigma_px: sigma, ..BundleConfig::default() };
        no_panic("bundle_adjust", || bundle_adjust(&mut problem, &cfg))?;
    }

    #[test]
    fn evaluation_never_panics(
        a in prop::collection::vec((wild_f64(), wild_f64(), wild_f64(), wild_f64()), 0..12),
        b in prop::collection::vec((wild_f64(), wild_f64(), wild_f64(), wild_f64()), 0..12),
        alignment in 0u8..3,
        max_dt in wild_f64(),
    ) {
        let trajectory = |v: &[(f64, f64, f64, f64)]| Trajectory::new(v.iter().map(|&(t, x, y, z)| {
            (t, Isometry3::new(Vector3::new(x, y, z), Vector3::new(0.0, 0.001 * x, 0.0)))
        }).collect());
        let (gt, est) = (trajectory(&a), trajectory(&b));
        let cfg = EvalConfig {
            alignment: [Alignment::None, Alignment::Se3, Alignment::Sim3][alignment as usize],
            max_dt,
        };
        no_panic("ate", || ate(&gt, &est, &cfg))?;
        no_panic("rpe", || rpe(&gt, &est, &cfg))?;
    }

    #[test]
    fn camera_models_never_panic(
        k in (wild_f64(), wild_f64(), wild_f64(), wild_f64()),
        d in (wild_f64(), wild_f64(), wild_f64(), wild_f64(), wild_f64()),
        cam in wild_camera(),
        p in (wild_f64(), wild_f64(), wild_f64()),
        size in (0usize..24, 0usize..24),
    ) {
        let lenses: Vec<Lens> = [
            KannalaBrandt::new([k.0, k.1, k.2, k.3]).ok().map(Lens::from),
            Some(Lens::from(Distortion::from_array([d.0, d.1, d.2, d.3, d.4]))),
        ].into_iter().flatten().collect();
        for lens in lenses {
            let c = Camera::new(cam.pinhole, lens);
            let point = Vector3::new(p.0, p.1, p.2);
            no_panic("Camera::project", || c.project(&point).map(|u| (c.bearing(&u), c.pixel_to_normalized(&u))))?;
            no_panic("Camera::project_jacobian", || c.project_jacobian(&point))?;
            no_panic("UndistortMap::new", || UndistortMap::new(&c, &cam.pinhole, size.0, size.1))?;
        }
    }

    #[test]
    fn features_never_panic(img1 in gray(), img2 in gray(), n in 0usize..300) {
        let orb = Orb::new(OrbConfig { n_features: n, ..OrbConfig::default() });
        no_panic("Orb::detect_and_describe", || {
            if let Ok(orb) = &orb {
                let f1 = orb.detect_and_describe(&img1);
                let f2 = orb.detect_and_describe(&img2);
                if let (Ok(f1), Ok(f2)) = (f1, f2) {
                    drop(match_descriptors(f1.descriptors(), f2.descriptors(), &MatchConfig::default()));
                }
            }
        })?;
        let d: Vec<Descriptor> = (0..n % 7).map(|k| Descriptor([k as u64; 4])).collect();
        no_panic("match_descriptors", || match_descriptors(&d, &[], &MatchConfig::default()))?;
        no_panic("TwoViewEstimator::relative_pose", || {
            TwoViewEstimator::default().relative_pose(&img1, &img2, &camera())
        })?;
    }

    #[test]
    fn direct_aligners_never_panic(p1 in plane(), p2 in plane(), depth in plane(), shift in (wild_f64(), wild_f64())) {
        no_panic("align_translation", || align_translation(&p1, &p2, &TranslationConfig::default()))?;
        no_panic("align_translation, same plane", || align_translation(&p1, &p1, &TranslationConfig::default()))?;
        let init = Matrix3::new(1.0, 0.0, shift.0, 0.0, 1.0, shift.1, 0.0, 0.0, 1.0);
        no_panic("align_affine", || align_affine(&p1, &p2, &init, &WarpConfig::default()))?;
        no_panic("align_homography", || align_homography(&p1, &p2, &init, &WarpConfig::default()))?;
        no_panic("good_features_to_track", || good_features_to_track(&p1, 50, 0.01, 3.0))?;
        let pts = vec![
            nalgebra::Vector2::new(shift.0 as f32, shift.1 as f32),
            nalgebra::Vector2::new(10.0, 10.0),
        ];
        no_panic("track_klt", || track_klt(&p1, &p2, &pts, &KltConfig::default()))?;
        no_panic("track_klt, same plane", || track_klt(&p1, &p1, &pts, &KltConfig::default()))?;
        no_panic("RgbdFrame / align_se3", || {
            if let Ok(frame) = RgbdFrame::new(p1.clone(), depth.clone(), &camera()) {
                let prior = Isometry3::translation(shift.0, shift.1, 0.0);
                drop(align_se3(&frame, &p2, &prior, &Se3Config::default()));
                drop(align_se3(&frame, &p1, &Isometry3::identity(), &Se3Config::default()));
                drop(photometric_residual_map(&frame, &p2, &prior, 1.0, 0.0));
            }
        })?;
    }

    #[test]
    fn trackers_never_panic(frames in prop::collection::vec((gray(), 0u8..3, wild_f32()), 1..4), timestamps in prop::collection::vec(wild_f64(), 4)) {
        // Frame::new refuses a non-finite timestamp and a depth map of another size; the
        // trackers get the frames it accepts.
        let mut accepted = Vec::new();
        for ((image, depth_kind, z), timestamp) in frames.into_iter().zip(timestamps) {
            let (w, h) = image.size();
            let depth = match depth_kind {
                0 => None,
                1 => Some(Image::filled(w, h, z)),
                _ => Some(Image::filled(w / 2 + 1, h, 2.0)),
            };
            let valid = timestamp.is_finite() && depth.as_ref().is_none_or(|d| d.size() == (w, h));
            let frame = Frame::new(timestamp, image, depth);
            prop_assert_eq!(frame.is_ok(), valid, "{:?}", frame.as_ref().err());
            accepted.extend(frame.ok());
        }
        let frames = accepted;
        no_panic("DirectTracker::track", || {
            let mut t = DirectTracker::new(camera(), DirectTrackerConfig::default());
            for f in &frames {
                drop(t.track(f));
            }
        })?;
        no_panic("FeatureRgbdTracker::track", || {
            if let Ok(mut t) = FeatureRgbdTracker::new(camera(), FeatureRgbdConfig::default()) {
                for f in &frames {
                    drop(t.track(f));
                }
            }
        })?;
        no_panic("MonoTracker::track", || {
            if let Ok(mut t) = MonoTracker::new(camera(), MonoConfig::default()) {
                for f in &frames {
                    drop(t.track(f));
                }
            }
        })?;
    }
}

/// A textured plane of `w x h` (large enough for every aligner).
fn texture(w: usize, h: usize, phase: f32) -> Image<f32> {
    let data = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f32, (i / w) as f32);
            128.0 + 50.0 * (0.3 * x + phase).sin() * (0.23 * y).cos() + 20.0 * (0.05 * x * y).sin()
        })
        .collect();
    Image::new(w, h, data).expect("w * h values")
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(vofront_fixtures::proptest_cases(24)))]

    /// Public configuration fields at their limits (zero, huge, NaN) on valid images.
    #[test]
    fn direct_configs_never_panic(
        levels in prop_oneof![0usize..4, 30usize..70],
        iterations in 0usize..4,
        budget in prop_oneof![Just(0usize), 1usize..50, Just(usize::MAX)],
        window in 0usize..40,
        x in wild_f32(),
        y in wild_f64(),
        w in 8usize..48,
    ) {
        let (p1, p2) = (texture(w, w, 0.0), texture(w, w, 0.4));
        let tcfg = TranslationConfig {
            levels,
            max_iterations: iterations,
            min_step: y,
            gradient_threshold: x,
            max_pixels: budget,
            min_sigma: x,
            max_condition: y,
            ..TranslationConfig::default()
        };
        no_panic("align_translation", || align_translation(&p1, &p2, &tcfg))?;
        let wcfg = WarpConfig {
            levels,
            max_iterations: iterations,
            min_step: y,
            min_relative_decrease: y,
            gradient_threshold: x,
            max_pixels: budget,
            min_sigma: x,
            max_condition: y,
            ..WarpConfig::default()
        };
        no_panic("align_homography", || align_homography(&p1, &p2, &Matrix3::identity(), &wcfg))?;
        let kcfg = KltConfig {
            window,
            levels,
            max_iterations: iterations,
            epsilon: x,
            min_eigenvalue: x,
            forward_backward: Some(x),
        };
        let pts = [nalgebra::Vector2::new(w as f32 / 2.0, w as f32 / 2.0)];
        no_panic("track_klt", || track_klt(&p1, &p2, &pts, &kcfg))?;
        no_panic("good_features_to_track", || good_features_to_track(&p1, budget, x, x))?;
        let depth = Image::filled(w, w, 2.0);
        let scfg = Se3Config {
            levels,
            pixel_budget: budget,
            gradient_threshold: x,
            brightness_levels: levels,
            max_gain: y,
            max_iterations: iterations,
            min_step: y,
            min_sigma: x,
            min_depth: x,
            max_condition: y,
            inlier_sigmas: x,
            ..Se3Config::default()
        };
        no_panic("align_se3", || {
            if let Ok(frame) = RgbdFrame::new(p1.clone(), depth.clone(), &camera()) {
                drop(align_se3(&frame, &p2, &Isometry3::identity(), &scfg));
            }
        })?;
    }

    #[test]
    fn orb_configs_never_panic(
        levels in 0usize..40,
        scale in wild_f32(),
        fast in any::<u8>(),
        edge in 0usize..80,
        patch in 0usize..80,
        n in 0usize..3000,
        floor in 0usize..200,
    ) {
        let cfg = OrbConfig {
            n_features: n,
            scale_levels: levels,
            scale_factor: scale,
            fast_threshold: fast,
            min_fast_threshold: fast / 2,
            edge_threshold: edge,
            patch_size: patch,
            cell_floor: floor,
            ..OrbConfig::default()
        };
        let data = (0..160 * 120).map(|i| ((i % 160 * 7 + i / 160 * 13) % 256) as u8).collect();
        let img = Image::new(160, 120, data).expect("160 * 120 values");
        no_panic("Orb", || Orb::new(cfg.clone()).map(|orb| orb.detect_and_describe(&img)))?;
    }
}

#[test]
fn inconsistent_feature_arrays_are_an_error() {
    let one = |n: usize| vec![1.0f32; n];
    let built = |levels: usize, descriptors: usize| {
        Features::new(
            one(1),
            one(1),
            vec![0; levels],
            one(1),
            one(1),
            one(1),
            vec![Descriptor([1, 0, 0, 0]); descriptors],
        )
    };
    assert!(built(0, 1).is_err());
    assert!(built(1, 0).is_err());
    let good = built(1, 1).expect("equal lengths");
    let cfg = MatchConfig::default();
    assert!(match_windowed(&good, &[], &good, 5.0, None, &cfg).is_err());
    assert!(match_windowed(&good, &[(10.0, 10.0)], &good, 5.0, None, &cfg).is_ok());
}

#[test]
fn a_short_plane_buffer_is_an_error_not_a_panic() {
    // The case of the issue: 64 x 64 with 10 values used to reach `align_translation`.
    assert!(Image::<f32>::new(64, 64, vec![0.0; 10]).is_err());
    assert!(Image::<f32>::new(usize::MAX, 2, Vec::new()).is_err());
}
