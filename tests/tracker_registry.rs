//! One tracker registry behind every front-end: a rendered EuRoC sequence whose camera is
//! mounted on the body by a non-identity `T_BS`, tracked from Rust
//! (`vofront::odometry::registry`) and by `vofront odometry`, gives the same trajectory and
//! the same ATE, both against the CAMERA ground truth (body poses times `T_BS`).
//! `python/tests/test_odometry_eval.py` compares Python's `run_odometry` with the CLI on the
//! same kind of folder.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use nalgebra::Isometry3;
use serde_json::Value;
use vofront::dataset::Dataset;
use vofront::eval::Alignment;
use vofront::odometry::registry::{
    CameraOrigin, OdometryError, Session, TrackerKind, TrackerOptions,
};
use vofront::odometry::run::{FrameRecord, RunControl};
use vofront::trajectory::Trajectory;
use vofront_fixtures::euroc::{mounted_camera_in_body, write_euroc_sequence};
use vofront_fixtures::scene::{default_camera, room_trajectory, Scene};

/// Frames of the rendered sequence (enough for the monocular initialisation and a few
/// keyframes, short enough for CI).
const FRAMES: usize = 30;
/// ATE bound of the monocular tracker on the noiseless rendering, metres (Sim(3)-aligned;
/// ~1.5 mm is typical).
const ATE_M: f64 = 0.005;

fn vofront(args: &[&str], cwd: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_vofront"))
        .args(args)
        .current_dir(cwd)
        .output()
        .expect("run vofront")
}

/// A fresh folder holding the rendered EuRoC sequence `seq/` of `frames` frames; the true
/// camera poses.
fn euroc_sequence(name: &str, frames: usize) -> (PathBuf, Vec<Isometry3<f64>>) {
    let dir = std::env::temp_dir().join(format!("vofront-registry-{name}-{}", std::process::id()));
    std::fs::remove_dir_all(&dir).ok();
    let poses = room_trajectory(frames);
    let t_bs = mounted_camera_in_body(std::f64::consts::FRAC_PI_2);
    write_euroc_sequence(
        &dir.join("seq"),
        &Scene::box_room(1),
        &default_camera(),
        (640, 480),
        &poses,
        &t_bs,
    )
    .unwrap();
    (dir, poses)
}

#[test]
fn registry_and_cli_track_a_mounted_euroc_camera_alike_against_the_camera_ground_truth() {
    let (dir, truth) = euroc_sequence("mono", FRAMES);
    let session = Session::new(
        Dataset::open(dir.join("seq")).unwrap(),
        TrackerKind::Mono,
        None,
    )
    .unwrap();
    assert!(
        matches!(session.camera_origin, CameraOrigin::Dataset(Some(_))),
        "{:?}",
        session.camera_origin
    );
    let mut tracker = session.tracker(&TrackerOptions::default()).unwrap();
    let mut no_sink = |_: &FrameRecord| Ok::<(), std::io::Error>(());
    let out = session
        .run(tracker.as_mut(), &RunControl::default(), &mut no_sink)
        .unwrap();
    assert_eq!((out.summary.frames, out.trajectory.len()), (FRAMES, FRAMES));

    // The evaluation is against the camera poses the frames were rendered from.
    let evaluation = session.evaluate(&out.trajectory).unwrap();
    assert_eq!(evaluation.alignment, Alignment::Sim3);
    assert_eq!(evaluation.ground_truth.len(), FRAMES);
    for ((_, gt), want) in evaluation.ground_truth.poses.iter().zip(&truth) {
        let error = (gt.inverse() * want).translation.vector.norm();
        assert!(error < 1e-6, "camera ground truth off by {error} m");
    }
    let rust_ate = evaluation.ate.as_ref().unwrap().stats.rmse;
    assert!(rust_ate < ATE_M, "ATE {rust_ate} m");
    // The published poses are the body's, a lever arm of |t_BS| away from the camera's.
    let lever = mounted_camera_in_body(std::f64::consts::FRAC_PI_2)
        .translation
        .vector
        .norm();
    let body = session.dataset.ground_truth.as_ref().unwrap();
    for ((_, t_wb), (_, t_wc)) in body.poses.iter().zip(&evaluation.ground_truth.poses) {
        let arm = (t_wb.translation.vector - t_wc.translation.vector).norm();
        assert!((arm - lever).abs() < 1e-6, "{arm} m, T_BS {lever} m");
    }

    // The CLI, under the name and under the former name, gives the same trajectory and ATE.
    for method in ["mono", "feature"] {
        let traj = format!("{method}.txt");
        let run = vofront(
            &[
                "odometry",
                "seq",
                "--method",
                method,
                "--json",
                "--out",
                &traj,
                "--metrics",
                "m.csv",
            ],
            &dir,
        );
        assert!(
            run.status.success(),
            "{}",
            String::from_utf8_lossy(&run.stderr)
        );
        let json: Value = serde_json::from_slice(&run.stdout).unwrap();
        assert_eq!(json["method"], "mono");
        assert_eq!(json["ate"]["alignment"], "sim3");
        let cli_ate = json["ate"]["rmse"].as_f64().unwrap();
        assert!(
            (cli_ate - rust_ate).abs() <= 1e-9 * rust_ate,
            "{method}: CLI ATE {cli_ate} m, Rust {rust_ate} m"
        );
        let cli = Trajectory::read_tum(&dir.join(&traj)).unwrap();
        assert_eq!(cli.len(), out.trajectory.len());
        for ((t1, p1), (t2, p2)) in cli.poses.iter().zip(&out.trajectory.poses) {
            assert!((t1 - t2).abs() < 1e-6, "{t1} {t2}");
            let error = (p1.inverse() * p2).translation.vector.norm();
            assert!(error < 1e-6, "{method}: frame {t1} differs by {error} m");
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn depth_trackers_refuse_a_sequence_without_depth_alike() {
    let (dir, _) = euroc_sequence("depth", 2);
    let dataset = Dataset::open(dir.join("seq")).unwrap();
    for kind in TrackerKind::ALL.iter().filter(|k| k.needs_depth()) {
        let err = Session::new(dataset.clone(), *kind, None).unwrap_err();
        assert!(matches!(err, OdometryError::NoDepth { .. }), "{err}");
        let run = vofront(&["odometry", "seq", "--method", kind.name()], &dir);
        assert_eq!(run.status.code(), Some(1));
        let stderr = String::from_utf8_lossy(&run.stderr);
        let why = format!("seq: the {kind} method needs depth, and this dataset has none");
        assert!(err.to_string().ends_with(&why), "{err}");
        assert_eq!(stderr.trim(), format!("vofront: {why}"));
    }
    std::fs::remove_dir_all(&dir).ok();
}
