//! The `rerun` feature: a rendered street drive (a KITTI folder with ground truth) tracked by
//! the monocular tracker and logged to an `.rrd` file, read back with Rerun's own decoder:
//! every entity of `odometry::rerun_log` is there, one image per frame on the `frame`
//! timeline, keypoints and map points with each frame; the stereo, direct-stereo and direct
//! trackers' details (left keypoints by role; keyframe pixels by photometric residual) on
//! rendered stereo and RGB-D sequences; a path that cannot be written is an error before any
//! frame is tracked.

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
use vofront::odometry::observe::{FrameDetails, FrameObserver, Observed};
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

/// Runs `tracker` over `dataset` with a [`RerunSink`] writing `rrd`, checking each frame's
/// details with `check` (the frame observed, its details); returns the recording read back.
fn observe_into(
    dataset: &Dataset,
    tracker: &mut dyn vofront::odometry::Tracker,
    rrd: &Path,
    mut check: impl FnMut(&Observed<'_>, &FrameDetails),
) -> Recording {
    let camera = dataset
        .camera
        .unwrap_or_else(vofront_fixtures::scene::default_camera);
    let mut sink = RerunSink::save(rrd, camera).expect("sink");
    let mut observer = |o: &Observed<'_>| {
        let details = o
            .details
            .expect("every tracker keeps details when observed");
        assert_eq!(details.keypoints.len(), details.roles.len());
        check(o, details);
        sink.frame(o)
    };
    run_observed(
        dataset,
        tracker,
        &RunControl::default(),
        &mut |_: &_| Ok(()),
        &mut observer,
    )
    .expect("run");
    sink.finish().expect("finish");
    read_rrd(rrd)
}

/// The keypoints and map points of every frame of `recording` (`frames` of them).
fn assert_details_logged(recording: &Recording, frames: usize, what: &str) {
    let every_frame: Vec<i64> = (0..frames as i64).collect();
    for path in [entity::KEYPOINTS, entity::MAP_POINTS] {
        let mut logged = recording.frames.get(path).cloned().unwrap_or_default();
        logged.sort_unstable();
        assert_eq!(logged, every_frame, "{what}: {path}");
    }
}

/// A direct tracker's details after a frame aligned to its keyframe (`o`): the keyframe's
/// pixels warped into the frame with the residuals of the aligned pose (inliers in the share
/// the aligner found), inside the image, and the keyframe's points.
fn check_photometric(o: &Observed<'_>, details: &FrameDetails, size: (usize, usize), what: &str) {
    let n = details.keypoints.len();
    assert!(n >= 100, "{what}: {n} pixels");
    assert_eq!(details.residuals.len(), n, "{what}");
    assert!(details.residual_limit > 0.0, "{what}");
    let (inliers, outliers, unmatched) = details.role_counts();
    assert_eq!(unmatched, 0, "{what}");
    let share = inliers as f64 / (inliers + outliers) as f64;
    let aligner = o.estimate.quality.inlier_ratio;
    assert!(
        (share - aligner).abs() < 0.03 && share > 0.5,
        "{what}: {inliers} of {n} pixels are inliers, the aligner found {aligner}"
    );
    let mut abs: Vec<f32> = details.residuals.iter().map(|r| r.abs()).collect();
    abs.sort_by(f32::total_cmp);
    // Gaussian residuals have their median at 0.67 sigma, a fifth of the 3-sigma bound: a
    // warp that missed the aligned pose would put it near or past the bound.
    let median = abs[n / 2];
    assert!(
        median < 0.4 * details.residual_limit,
        "{what}: median |r| {median} grey levels, bound {}",
        details.residual_limit
    );
    let (w, h) = (size.0 as f32, size.1 as f32);
    assert!(
        details
            .keypoints
            .iter()
            .all(|&[x, y]| (0.0..w).contains(&x) && (0.0..h).contains(&y)),
        "{what}: a pixel outside the image"
    );
    assert!(!details.map_points.is_empty(), "{what}: no points");
}

#[test]
fn stereo_and_direct_stereo_log_their_details() {
    use vofront::odometry::direct_stereo::{DirectStereoConfig, DirectStereoTracker};
    use vofront::odometry::stereo::{StereoTracker, StereoTrackerConfig};
    use vofront_fixtures::stereo::{write_kitti_stereo, StereoSequence};

    let frames = 6;
    let dir = TempDir::new("stereo");
    let sequence = StereoSequence::driving(7, frames);
    write_kitti_stereo(&dir.0, &sequence).expect("write");
    let dataset = Dataset::open(&dir.0).expect("dataset");
    let rig = dataset.rig.expect("a stereo rig");
    let size = (sequence.size.0 as usize, sequence.size.1 as usize);

    let mut stereo = StereoTracker::new(rig, StereoTrackerConfig::default()).expect("stereo");
    let mut located = 0;
    let recording = observe_into(&dataset, &mut stereo, &dir.0.join("stereo.rrd"), |o, d| {
        let (i, tracked) = (o.index, o.estimate.status != TrackStatus::Lost);
        assert!(tracked, "stereo frame {i} lost");
        assert!(!d.keypoints.is_empty() && d.residuals.is_empty());
        assert!(!d.map_points.is_empty(), "frame {i}: no map points");
        // The first frame makes the map (no PnP); the others are located in it.
        let (inliers, _, _) = d.role_counts();
        if i > 0 {
            assert!(inliers >= 50, "frame {i}: {inliers} inliers");
            located += 1;
        }
    });
    assert_eq!(located, frames - 1);
    assert_details_logged(&recording, frames, "stereo");

    let mut direct =
        DirectStereoTracker::new(rig, DirectStereoConfig::default()).expect("direct stereo");
    let mut aligned = 0;
    let recording = observe_into(&dataset, &mut direct, &dir.0.join("direct.rrd"), |o, d| {
        let (i, tracked) = (o.index, o.estimate.status != TrackStatus::Lost);
        assert!(tracked, "direct-stereo frame {i} lost");
        if i > 0 {
            check_photometric(o, d, size, &format!("direct-stereo frame {i}"));
            aligned += 1;
        }
    });
    assert_eq!(aligned, frames - 1);
    assert_details_logged(&recording, frames, "direct-stereo");
}

#[test]
fn the_direct_tracker_logs_its_pixels_by_residual() {
    use vofront::odometry::direct::{DirectTracker, DirectTrackerConfig};
    use vofront_fixtures::scene::{default_camera, room_trajectory, Scene};
    use vofront_fixtures::tum::write_tum_sequence;

    let frames = 6;
    let dir = TempDir::new("direct");
    let camera = default_camera();
    write_tum_sequence(
        &dir.0,
        &Scene::box_room(5),
        &camera,
        (640, 480),
        &room_trajectory(frames),
    )
    .expect("write");
    let dataset = Dataset::open(&dir.0).expect("dataset");
    let mut direct = DirectTracker::new(camera, DirectTrackerConfig::default());
    let mut aligned = 0;
    let recording = observe_into(&dataset, &mut direct, &dir.0.join("direct.rrd"), |o, d| {
        let (i, tracked) = (o.index, o.estimate.status != TrackStatus::Lost);
        assert!(tracked, "direct frame {i} lost");
        if i > 0 {
            check_photometric(o, d, (640, 480), &format!("direct frame {i}"));
            aligned += 1;
        }
    });
    assert_eq!(aligned, frames - 1);
    assert_details_logged(&recording, frames, "direct");
}
