//! ROS 2 bags (`.mcap`) as datasets: bags written here with the `mcap` crate from rendered
//! fixtures and hand-made messages (every encoding, compressed images, calibrations, topics,
//! stamps), damaged bags (cut off, corrupted CDR, random bytes) and a tracked sequence that
//! must match its image folder.

use std::fs;
use std::io::Cursor;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use image::{DynamicImage, GrayImage, ImageFormat, Luma};
use proptest::prelude::*;
use proptest::test_runner::{Config, RngAlgorithm, TestRng, TestRunner};
use vofront::core::{Camera, Distortion, KannalaBrandt, Lens, Pinhole};
use vofront::dataset::bag::write::{
    camera_info_message, camera_message, compressed_image_message, image_message, BagWriter,
    ImageLayout,
};
use vofront::dataset::bag::{messages, BagError, BagTopics, MessageError};
use vofront::dataset::{CameraSource, Dataset, DatasetConfig, DatasetError, DatasetKind};
use vofront::odometry::registry::{Session, TrackerKind, TrackerOptions};
use vofront::odometry::run::{FrameRecord, RunControl};
use vofront_fixtures::scene::{default_camera, room_trajectory, Scene};
use vofront_fixtures::tum::write_tum_sequence;

/// A fresh folder under the system temp dir, removed on drop.
struct TempDir(PathBuf);

impl TempDir {
    fn new(tag: &str) -> Self {
        static COUNTER: AtomicUsize = AtomicUsize::new(0);
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let dir =
            std::env::temp_dir().join(format!("vofront-bag-{tag}-{}-{n}", std::process::id()));
        fs::remove_dir_all(&dir).ok();
        fs::create_dir_all(&dir).expect("temp dir");
        Self(dir)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        fs::remove_dir_all(&self.0).ok();
    }
}

/// One message to write: topic, schema name, stamp (ns) and CDR bytes.
struct Msg {
    topic: &'static str,
    schema: &'static str,
    ns: u64,
    data: Vec<u8>,
}

/// How the bag is laid out.
#[derive(Clone, Copy)]
enum Layout {
    /// zstd chunks of about 1 MB (the writers' default).
    Chunked,
    /// One record after another, no chunks (every message readable up to a cut).
    Plain,
}

/// Writes `msgs` in order to an MCAP byte buffer.
fn bag_bytes(msgs: &[Msg], layout: Layout) -> Vec<u8> {
    let chunked = matches!(layout, Layout::Chunked);
    let mut w = BagWriter::new(Cursor::new(Vec::new()), chunked).expect("writer");
    for m in msgs {
        w.write(m.topic, m.schema, m.ns, &m.data).expect("message");
    }
    w.finish().expect("finish").into_inner()
}

fn write_bag(dir: &Path, name: &str, msgs: &[Msg], layout: Layout) -> PathBuf {
    let path = dir.join(name);
    fs::write(&path, bag_bytes(msgs, layout)).expect("write bag");
    path
}

/// A `sensor_msgs/msg/Image` of packed `rows`, each padded to `step` bytes.
fn image_msg(
    ns: u64,
    (width, height): (usize, usize),
    encoding: &str,
    big_endian: bool,
    step: usize,
    rows: &[u8],
) -> Vec<u8> {
    let layout = ImageLayout {
        width,
        height,
        encoding,
        big_endian,
        step,
    };
    image_message(ns, layout, rows)
}

fn mono8_msg(topic: &'static str, ns: u64, img: &GrayImage) -> Msg {
    let (w, h) = (img.width() as usize, img.height() as usize);
    Msg {
        topic,
        schema: messages::IMAGE,
        ns,
        data: image_msg(ns, (w, h), "mono8", false, w, img.as_raw()),
    }
}

/// A small grey test pattern: value `(7 x + 13 y + seed) mod 251`.
fn pattern(w: u32, h: u32, seed: u32) -> GrayImage {
    GrayImage::from_fn(w, h, |x, y| Luma([((7 * x + 13 * y + seed) % 251) as u8]))
}

fn expect_bag_error(result: Result<Dataset, DatasetError>) -> BagError {
    match result {
        Err(DatasetError::Bag(e)) => *e,
        other => panic!("expected a bag error, got {other:?}"),
    }
}

#[test]
fn rendered_sequence_tracks_alike_as_folder_and_as_bag() {
    let dir = TempDir::new("rendered");
    let seq = dir.0.join("seq");
    let mut camera = default_camera();
    camera.pinhole = Pinhole::new(131.25, 131.25, 79.5, 59.5).unwrap();
    write_tum_sequence(
        &seq,
        &Scene::box_room(5),
        &camera,
        (160, 120),
        &room_trajectory(8),
    )
    .unwrap();
    let folder = Dataset::open(&seq).unwrap();

    // The same files as messages: rgb8 with a padded row step, 16UC1 depth in TUM units.
    let mut msgs = Vec::new();
    for f in &folder.frames {
        let ns = (f.timestamp * 1e9).round() as u64;
        let rgb = image::open(&f.image).unwrap().into_rgb8();
        let depth = image::open(f.depth.as_ref().unwrap())
            .unwrap()
            .into_luma16();
        let le: Vec<u8> = depth
            .as_raw()
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        msgs.push(Msg {
            topic: "/cam/rgb/image",
            schema: messages::IMAGE,
            ns,
            data: image_msg(ns, (160, 120), "rgb8", false, 3 * 160 + 5, rgb.as_raw()),
        });
        msgs.push(Msg {
            topic: "/cam/depth/image",
            schema: messages::IMAGE,
            ns,
            data: image_msg(ns, (160, 120), "16UC1", false, 2 * 160, &le),
        });
        msgs.push(Msg {
            topic: "/cam/rgb/camera_info",
            schema: messages::CAMERA_INFO,
            ns,
            data: camera_message(ns, (160, 120), &camera),
        });
    }
    let path = write_bag(&dir.0, "seq.mcap", &msgs, Layout::Chunked);
    let mut bag = Dataset::open(&path).unwrap();
    assert_eq!((bag.kind, bag.len()), (DatasetKind::Bag, folder.len()));
    assert_eq!(bag.camera, Some(camera));
    assert_eq!(
        bag.camera_source,
        Some(CameraSource::Topic("/cam/rgb/camera_info".into()))
    );
    assert!(bag.notes().is_empty(), "{:?}", bag.notes());
    bag.depth_scale = Some(5000.0);
    for i in 0..bag.len() {
        let (a, b) = (folder.load(i).unwrap(), bag.load(i).unwrap());
        assert!((a.timestamp() - b.timestamp()).abs() < 1e-9);
        assert_eq!(a.image(), b.image(), "frame {i}");
        assert_eq!(a.depth(), b.depth(), "frame {i}");
    }

    let run = |dataset: Dataset, given: Option<(Camera, &str)>| {
        let session = Session::new(dataset, TrackerKind::Direct, given).unwrap();
        let mut tracker = session.tracker(&TrackerOptions::default()).unwrap();
        let mut sink = |_: &FrameRecord| Ok::<(), std::io::Error>(());
        session
            .run(tracker.as_mut(), &RunControl::default(), &mut sink)
            .unwrap()
            .trajectory
    };
    let (a, b) = (run(folder, Some((camera, "test"))), run(bag, None));
    assert_eq!(a.len(), 8);
    assert_eq!(a.len(), b.len());
    for ((_, pa), (_, pb)) in a.poses.iter().zip(&b.poses) {
        assert!((pa.to_homogeneous() - pb.to_homogeneous()).abs().max() < 1e-6);
    }
}

#[test]
fn every_encoding_decodes_to_the_expected_pixels() {
    let (w, h) = (5usize, 3usize);
    let grey = pattern(w as u32, h as u32, 40);
    let g = grey.as_raw();
    let expect = vofront::image::Image::from_gray_owned(grey.clone());
    let colour =
        |order: &dyn Fn(u8) -> Vec<u8>| g.iter().flat_map(|&v| order(v)).collect::<Vec<u8>>();
    for (encoding, bpp, rows) in [
        ("mono8", 1, g.clone()),
        ("rgb8", 3, colour(&|v| vec![v, v, v])),
        ("bgr8", 3, colour(&|v| vec![v, v, v])),
        ("rgba8", 4, colour(&|v| vec![v, v, v, 255])),
        ("bgra8", 4, colour(&|v| vec![v, v, v, 0])),
    ] {
        let msg = image_msg(0, (w, h), encoding, false, w * bpp + 3, &rows);
        assert_eq!(
            messages::intensity(&msg, false).unwrap(),
            expect,
            "{encoding}"
        );
    }
    // Channel order matters: pure red in rgb8 is pure blue in bgr8.
    let red = image_msg(0, (1, 1), "rgb8", false, 3, &[255, 0, 0]);
    let blue = image_msg(0, (1, 1), "bgr8", false, 3, &[255, 0, 0]);
    assert_eq!(messages::intensity(&red, false).unwrap().at(0, 0), 54);
    assert_eq!(messages::intensity(&blue, false).unwrap().at(0, 0), 18);

    // 16-bit: v * 257 reads back as v, in either byte order (is_bigendian) and CDR order.
    let wide: Vec<u16> = g.iter().map(|&v| u16::from(v) * 257).collect();
    for big in [false, true] {
        let bytes: Vec<u8> = wide
            .iter()
            .flat_map(|v| {
                if big {
                    v.to_be_bytes()
                } else {
                    v.to_le_bytes()
                }
            })
            .collect();
        let msg = image_msg(0, (w, h), "mono16", big, 2 * w + 2, &bytes);
        assert_eq!(
            messages::intensity(&msg, false).unwrap(),
            expect,
            "mono16 big-endian {big}"
        );
    }

    // Depth: 16UC1 in millimetres (scale 1000), 32FC1 in metres with NaN/negative as no depth.
    let mm: Vec<u8> = [1500u16, 0, 65535]
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    let d16 =
        messages::depth(&image_msg(0, (3, 1), "16UC1", false, 6, &mm), false, 1000.0).unwrap();
    assert_eq!(
        (d16.at(0, 0), d16.at(1, 0), d16.at(2, 0)),
        (1.5, 0.0, 65.535)
    );
    let m: Vec<u8> = [2.25f32, f32::NAN, -1.0]
        .iter()
        .flat_map(|v| v.to_be_bytes())
        .collect();
    let d32 = messages::depth(&image_msg(0, (3, 1), "32FC1", true, 12, &m), false, 1000.0).unwrap();
    assert_eq!((d32.at(0, 0), d32.at(1, 0), d32.at(2, 0)), (2.25, 0.0, 0.0));

    // Unknown encodings, depth as intensity and short data are typed errors.
    let yuv = image_msg(0, (2, 1), "yuv422", false, 4, &[0; 4]);
    assert!(
        matches!(messages::intensity(&yuv, false), Err(MessageError::Encoding { encoding, .. }) if encoding == "yuv422")
    );
    let depth_as_grey = image_msg(0, (3, 1), "16UC1", false, 6, &mm);
    assert!(matches!(
        messages::intensity(&depth_as_grey, false),
        Err(MessageError::Encoding { .. })
    ));
    let mut short = image_msg(0, (5, 3), "mono8", false, 5, g);
    short.truncate(short.len() - 4);
    assert!(matches!(
        messages::intensity(&short, false),
        Err(MessageError::Cdr(_))
    ));
    let lying = image_msg(0, (5, 3), "mono8", false, 4, &[0; 12]);
    assert!(matches!(
        messages::intensity(&lying, false),
        Err(MessageError::Layout { .. })
    ));
}

#[test]
fn compressed_png_is_exact_and_jpeg_close() {
    let grey = pattern(32, 24, 3);
    let encode = |format: ImageFormat| {
        let mut bytes = Cursor::new(Vec::new());
        DynamicImage::ImageLuma8(grey.clone())
            .write_to(&mut bytes, format)
            .unwrap();
        bytes.into_inner()
    };
    let png = messages::intensity(
        &compressed_image_message(0, "png", &encode(ImageFormat::Png)),
        true,
    )
    .unwrap();
    assert_eq!(png, vofront::image::Image::from_gray_owned(grey.clone()));
    // JPEG: what the image crate decodes from the same bytes, near the original.
    let jpeg_bytes = encode(ImageFormat::Jpeg);
    let jpeg =
        messages::intensity(&compressed_image_message(0, "jpeg", &jpeg_bytes), true).unwrap();
    let decoded = image::load_from_memory(&jpeg_bytes).unwrap().into_luma8();
    assert_eq!(jpeg, vofront::image::Image::from_gray_owned(decoded));
    let mean_error = grey
        .enumerate_pixels()
        .map(|(x, y, p)| (f64::from(jpeg.at(x as usize, y as usize)) - f64::from(p[0])).abs())
        .sum::<f64>()
        / f64::from(32 * 24);
    assert!(mean_error < 8.0, "jpeg mean error {mean_error}");
    let garbage = compressed_image_message(0, "png", &[1, 2, 3]);
    assert!(matches!(
        messages::intensity(&garbage, true),
        Err(MessageError::Compressed { .. })
    ));
}

#[test]
fn camera_info_models_become_cameras_or_clear_errors() {
    let k = [500.0, 501.0, 320.0, 240.0];
    let info = |model: &str, d: &[f64]| {
        messages::camera_info(&camera_info_message(5, (640, 480), model, d, k, 0.0))
    };
    let pinhole = Pinhole::new(500.0, 501.0, 320.0, 240.0).unwrap();
    let plumb = info("plumb_bob", &[0.1, -0.2, 0.001, 0.002, 0.05]).unwrap();
    assert_eq!(
        plumb.camera,
        Camera::new(
            pinhole,
            Distortion::from_array([0.1, -0.2, 0.001, 0.002, 0.05])
        )
    );
    assert_eq!((plumb.size, plumb.stamp), ((640, 480), 5e-9));
    let rational = info(
        "rational_polynomial",
        &[0.1, -0.2, 0.001, 0.002, 0.05, 0.0, 0.0, 0.0],
    )
    .unwrap();
    assert_eq!(rational.camera, plumb.camera);
    let fisheye = info("equidistant", &[0.01, -0.02, 0.003, -0.001]).unwrap();
    assert_eq!(
        fisheye.camera.distortion,
        Lens::from(KannalaBrandt::new([0.01, -0.02, 0.003, -0.001]).unwrap())
    );
    assert_eq!(info("", &[]).unwrap().camera, Camera::pinhole(pinhole));
    let round_trip = |c: Camera| messages::camera_info(&camera_message(0, (640, 480), &c)).unwrap();
    assert_eq!(round_trip(fisheye.camera).camera, fisheye.camera);
    assert_eq!(round_trip(plumb.camera).camera, plumb.camera);
    let err = info(
        "rational_polynomial",
        &[0.1, -0.2, 0.0, 0.0, 0.0, 0.3, 0.0, 0.0],
    )
    .unwrap_err();
    assert!(err.to_string().contains("k4..k6"), "{err}");
    assert!(matches!(
        info("fov", &[0.9]),
        Err(MessageError::Calibration(_))
    ));
    let zero = messages::camera_info(&camera_info_message(
        0,
        (640, 480),
        "plumb_bob",
        &[0.0; 5],
        [0.0; 4],
        0.0,
    ));
    assert!(matches!(zero, Err(MessageError::Camera(_))));
}

#[test]
fn topics_are_picked_matched_by_stamp_and_named_in_errors() {
    let dir = TempDir::new("topics");
    let img = pattern(8, 6, 1);
    let mm: Vec<u8> = vec![0x10; 8 * 6 * 2];
    let mut msgs = Vec::new();
    for i in 0..4u64 {
        let ns = 1_000_000_000 + i * 100_000_000;
        msgs.push(mono8_msg("/left/image_raw", ns, &img));
        msgs.push(mono8_msg("/right/image_raw", ns + 1_000_000, &img));
        // Depth 5 ms after each image, except the third (70 ms: no partner within 20 ms).
        let dns = ns + if i == 2 { 70_000_000 } else { 5_000_000 };
        msgs.push(Msg {
            topic: "/depth",
            schema: messages::IMAGE,
            ns: dns,
            data: image_msg(dns, (8, 6), "16UC1", false, 16, &mm),
        });
        msgs.push(Msg {
            topic: "/left/camera_info",
            schema: messages::CAMERA_INFO,
            ns,
            data: camera_info_message(ns, (8, 6), "plumb_bob", &[], [10.0, 10.0, 4.0, 3.0], 0.0),
        });
        msgs.push(Msg {
            topic: "/right/camera_info",
            schema: messages::CAMERA_INFO,
            ns,
            data: camera_info_message(ns, (8, 6), "plumb_bob", &[], [10.0, 10.0, 4.0, 3.0], -5.0),
        });
    }
    let path = write_bag(&dir.0, "two.mcap", &msgs, Layout::Chunked);
    let config = DatasetConfig::default();

    let err = expect_bag_error(Dataset::open(&path));
    let text = err.to_string();
    assert!(matches!(err, BagError::Ambiguous { .. }), "{text}");
    assert!(
        text.contains("/left/image_raw")
            && text.contains("/right/image_raw")
            && text.contains("--image-topic"),
        "{text}"
    );
    let missing = BagTopics {
        image: Some("/nope".into()),
        ..BagTopics::default()
    };
    assert!(matches!(
        expect_bag_error(Dataset::open_bag(&path, &config, &missing)),
        BagError::NotFound { .. }
    ));

    let topics = BagTopics {
        image: Some("/left/image_raw".into()),
        right: Some("/right/image_raw".into()),
        ..BagTopics::default()
    };
    let data = Dataset::open_bag(&path, &config, &topics).unwrap();
    // The one depth topic is picked; the image without depth is left out and noted.
    assert_eq!(data.len(), 3);
    assert_eq!(data.notes().len(), 1, "{:?}", data.notes());
    assert!(data.notes()[0].contains("1 of 4"), "{:?}", data.notes());
    let stamps: Vec<f64> = data.frames.iter().map(|f| f.timestamp).collect();
    assert_eq!(stamps, vec![1.0, 1.1, 1.3]);
    assert_eq!(
        data.camera_source,
        Some(CameraSource::Topic("/left/camera_info".into()))
    );
    // The right camera's P[0][3] = -fx * b = -5 makes a stereo rig of baseline 0.5.
    let rig = data.rig.as_ref().unwrap();
    assert!(rig.is_stereo() && (rig.baseline().unwrap() - 0.5).abs() < 1e-12);
    let frame = data.load_stereo(2).unwrap();
    assert_eq!(frame.right().unwrap().size(), (8, 6));
    assert!((frame.depth().unwrap().at(0, 0) - 4112.0 / 1000.0).abs() < 1e-6);

    let none = write_bag(&dir.0, "none.mcap", &msgs[3..4], Layout::Chunked);
    let err = expect_bag_error(Dataset::open(&none));
    assert!(matches!(err, BagError::NoTopic { .. }), "{err}");
}

/// A plain (unchunked) bag of `n` mono8 frames and its bytes.
fn frames_bag(n: u64) -> Vec<u8> {
    let msgs: Vec<Msg> = (0..n)
        .map(|i| mono8_msg("/cam/image", i * 50_000_000, &pattern(16, 12, i as u32)))
        .collect();
    bag_bytes(&msgs, Layout::Plain)
}

#[test]
fn a_bag_cut_off_yields_the_frames_before_the_cut() {
    let dir = TempDir::new("cut");
    let bytes = frames_bag(10);
    let path = dir.0.join("cut.mcap");
    fs::write(&path, &bytes[..bytes.len() * 6 / 10]).unwrap();
    let data = Dataset::open(&path).unwrap();
    assert!((4..10).contains(&data.len()), "{} frames", data.len());
    assert!(
        data.notes().iter().any(|n| n.contains("ends early")),
        "{:?}",
        data.notes()
    );
    for i in 0..data.len() {
        assert_eq!(
            data.load(i).unwrap().image(),
            &vofront::image::Image::from_gray_owned(pattern(16, 12, i as u32))
        );
    }
    fs::write(&path, &bytes[..5]).unwrap();
    assert!(matches!(
        expect_bag_error(Dataset::open(&path)),
        BagError::Read { .. }
    ));
}

#[test]
fn corrupted_cdr_is_a_typed_error_for_that_frame_only() {
    let dir = TempDir::new("cdr");
    let img = pattern(8, 6, 9);
    let mut msgs: Vec<Msg> = (0..3)
        .map(|i| mono8_msg("/cam/image", 1_000 + i, &img))
        .collect();
    msgs[1].data.truncate(30);
    let path = write_bag(&dir.0, "bad.mcap", &msgs, Layout::Chunked);
    let data = Dataset::open(&path).unwrap();
    assert_eq!(data.len(), 3);
    assert!(data.load(0).is_ok() && data.load(2).is_ok());
    match data.load(1) {
        Err(DatasetError::Bag(e)) => match *e {
            BagError::Message {
                topic,
                index,
                source: MessageError::Cdr(_),
                ..
            } => assert_eq!((topic.as_str(), index), ("/cam/image", 1)),
            other => panic!("expected a CDR error, got {other:?}"),
        },
        other => panic!("expected a CDR error, got {other:?}"),
    }
}

#[test]
fn random_bytes_and_random_cuts_never_panic() {
    let dir = TempDir::new("fuzz");
    let bytes = frames_bag(6);
    let path = dir.0.join("fuzz.mcap");
    let config = Config::with_cases(vofront_fixtures::proptest_cases(48));
    let rng = TestRng::deterministic_rng(RngAlgorithm::ChaCha);
    let mut runner = TestRunner::new_with_rng(config, rng);
    let strategy = (
        0..bytes.len(),
        proptest::collection::vec((0..bytes.len(), any::<u8>()), 0..4),
        any::<bool>(),
    );
    runner
        .run(&strategy, |(cut, flips, garbage)| {
            let mut b = if garbage {
                bytes.iter().map(|v| v.wrapping_mul(31)).collect()
            } else {
                bytes[..cut].to_vec()
            };
            for (at, v) in flips {
                if let Some(x) = b.get_mut(at) {
                    *x = v;
                }
            }
            fs::write(&path, &b).unwrap();
            if let Ok(data) = Dataset::open(&path) {
                for i in 0..data.len() {
                    data.load(i).ok();
                }
            }
            Ok(())
        })
        .unwrap();
}
