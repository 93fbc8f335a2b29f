//! The `rerun` feature: a rendered street drive (a KITTI folder with ground truth) tracked by
//! the monocular tracker and logged to an `.rrd` file, read back with Rerun's own decoder:
//! every entity of `odometry::rerun_log` is there, one image per frame on the `frame`
//! timeline, keypoints and map points with each frame; a path that cannot be written is an
//! error before any frame is tracked.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufReader;
use std::path::{Path, PathBuf};

use re_log_encoding::DecoderApp;
use rerun::log::{Chunk, LogMsg};
use vofront::dataset::Dataset;
use vofront::fixtures::driving::{DrivingSequence, FRAME_RATE};
use vofront::fixtures::image2d::to_gray8;
use vofront::odometry::mono::{MonoConfig, MonoTracker};
use vofront::odometry::observe::FrameObserver;
use vofront::odometry::observe::Observed;
use vofront::odometry::rerun_log::{self as entity, RerunLogError, RerunSink};
use vofront::odometry::run::{run_observed, RunControl};
use vofront::odometry::TrackStatus;
use vofront::trajectory::Trajectory;

/// Frames of the drive (the straight stretch: the map initialises within a few frames).
const FRAMES: usize = 10;

/// A temporary folder, removed on drop.
struct TempDir(PathBuf);

impl TempDir {
    fn new(name: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("vofront-rerun-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        Self(dir)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        std::fs::remove_dir_all(&self.0).ok();
    }
}

/// Writes `frames` of a rendered drive as a KITTI folder: `image_0/`, `times.txt`, `calib.txt`
/// (the drive's pinhole as `P0`) and `poses.txt` (its `T_wc`).
fn write_kitti_drive(dir: &Path, frames: usize) {
    let drive = DrivingSequence::new(5, frames);
    let k = drive.camera.pinhole;
    std::fs::create_dir_all(dir.join("image_0")).expect("image_0");
    let calib = format!("P0: {} 0 {} 0 0 {} {} 0 0 0 1 0\n", k.fx, k.cx, k.fy, k.cy);
    std::fs::write(dir.join("calib.txt"), calib).expect("calib");
    let times: String = (0..frames)
        .map(|i| format!("{:.6}\n", i as f64 / FRAME_RATE))
        .collect();
    std::fs::write(dir.join("times.txt"), times).expect("times");
    let truth = Trajectory::new(
        drive
            .poses_wc
            .iter()
            .enumerate()
            .map(|(i, p)| (i as f64 / FRAME_RATE, *p))
            .collect(),
    );
    std::fs::write(dir.join("poses.txt"), truth.to_kitti_string()).expect("poses");
    for i in 0..frames {
        let grey = to_gray8(&drive.render(i).image)
            .to_gray()
            .expect("grey image");
        grey.save(dir.join(format!("image_0/{i:06}.png")))
            .expect("png");
    }
}

/// What an `.rrd` file holds: per entity path (without the leading `/`), the rows logged on
/// the `frame` timeline (their frame numbers) and the static rows.
#[derive(Debug, Default)]
struct Recording {
    frames: BTreeMap<String, Vec<i64>>,
    statics: BTreeMap<String, usize>,
}

/// Decodes `path` with Rerun's decoder.
fn read_rrd(path: &Path) -> Recording {
    let file = BufReader::new(File::open(path).expect("open rrd"));
    let mut recording = Recording::default();
    for msg in DecoderApp::decode_lazy(file) {
        let LogMsg::ArrowMsg(_, arrow) = msg.expect("a well-formed message") else {
            continue;
        };
        let chunk = Chunk::from_arrow_msg(&arrow).expect("a chunk");
        let name = chunk
            .entity_path()
            .to_string()
            .trim_start_matches('/')
            .to_string();
        if chunk.is_static() {
            *recording.statics.entry(name).or_default() += chunk.num_rows();
        } else {
            let frame = chunk
                .timelines()
                .iter()
                .find(|(timeline, _)| timeline.as_str() == "frame")
                .map(|(_, column)| column.times_raw().to_vec())
                .expect("the frame timeline");
            recording.frames.entry(name).or_default().extend(frame);
        }
    }
    recording
}

#[test]
fn a_logged_drive_reads_back_with_every_entity_and_frame() {
    let dir = TempDir::new("drive");
    let seq = dir.0.join("seq");
    write_kitti_drive(&seq, FRAMES);
    let dataset = Dataset::open(&seq).expect("dataset");
    let camera = dataset.camera.expect("calib.txt camera");
    let ground_truth = dataset.camera_ground_truth().expect("poses.txt");
    let rrd = dir.0.join("drive.rrd");
    let mut sink = RerunSink::save(&rrd, camera)
        .expect("sink")
        .with_ground_truth(ground_truth);
    // Beside the sink, the details the tracker shows: the frames tracked have inliers.
    let mut tracked = 0;
    let mut inliers = Vec::new();
    let mut observer = |o: &Observed<'_>| {
        let details = o
            .details
            .expect("the mono tracker keeps details when observed");
        assert_eq!(details.keypoints.len(), details.roles.len());
        if o.estimate.status != TrackStatus::Lost {
            tracked += 1;
            inliers.push(details.role_counts().0);
        }
        sink.frame(o)
    };
    let mut tracker = MonoTracker::new(camera, MonoConfig::default()).expect("tracker");
    let control = RunControl::default();
    let out = run_observed(
        &dataset,
        &mut tracker,
        &control,
        &mut |_: &_| Ok(()),
        &mut observer,
    )
    .expect("run");
    sink.finish().expect("finish");
    assert_eq!(out.summary.frames, FRAMES);
    assert_eq!(
        out.trajectory.len(),
        FRAMES,
        "every frame tracked, some late"
    );
    // The first frame is the map's origin (no PnP); the frames after the initialisation
    // located by PnP show their inliers.
    assert!(tracked >= FRAMES - 4, "{tracked} tracked at once");
    assert!(
        inliers.iter().filter(|&&n| n >= 50).count() >= tracked - 2,
        "{inliers:?}"
    );

    let recording = read_rrd(&rrd);
    let every_frame: Vec<i64> = (0..FRAMES as i64).collect();
    for path in [
        entity::IMAGE,
        entity::KEYPOINTS,
        entity::MAP_POINTS,
        entity::INLIERS,
        entity::RESIDUAL,
        entity::TIME,
        entity::STATUS,
    ] {
        let mut frames = recording.frames.get(path).cloned().unwrap_or_default();
        frames.sort_unstable();
        assert_eq!(frames, every_frame, "{path}: {recording:?}");
    }
    for path in [entity::CAMERA, entity::TRAJECTORY] {
        assert_eq!(recording.frames[path].len(), tracked, "{path}");
    }
    assert!(!recording.frames[entity::VERDICT].is_empty());
    assert_eq!(recording.statics.get(entity::GROUND_TRUTH), Some(&1));
    assert_eq!(
        recording.statics.get(entity::IMAGE),
        Some(&1),
        "the pinhole"
    );
}

#[test]
fn an_unwritable_recording_is_an_error_naming_the_path() {
    let dir = TempDir::new("unwritable");
    let blocker = dir.0.join("a-file");
    std::fs::write(&blocker, "not a folder").expect("file");
    let path = blocker.join("out.rrd");
    let camera = DrivingSequence::new(1, 1).camera;
    let err = match RerunSink::save(&path, camera) {
        Ok(_) => panic!("a recording inside a file was accepted"),
        Err(e) => e,
    };
    assert!(matches!(err, RerunLogError::File { .. }), "{err:?}");
    assert!(err.to_string().contains("out.rrd"), "{err}");
}
