//! `vofront odometry` from the command line: a run stopped by SIGTERM / SIGINT leaves every
//! finished frame on disk in files that parse and that `vofront eval` accepts; outputs are
//! checked before the first frame; `--json`, `--max-frames 0` and the method names.

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

use serde_json::Value;
use vofront::trajectory::Trajectory;
use vofront_fixtures::faults::camera_for_width;
use vofront_fixtures::scene::{room_trajectory, Scene};
use vofront_fixtures::tum::write_tum_sequence;

/// Frames of the test sequence: enough that a run signalled after [`SIGNAL_AFTER`] frames is
/// still far from its end.
const FRAMES: usize = 240;
/// Finished frames (metrics lines) awaited before the signal is sent.
const SIGNAL_AFTER: usize = 10;
/// Image size of the test sequence.
const SIZE: (u32, u32) = (160, 120);

/// A 160x120 rendered room sequence, written once for all tests of this file.
fn sequence() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = std::env::temp_dir().join(format!("vofront-interrupt-{}", std::process::id()));
        write_tum_sequence(
            &dir.join("seq"),
            &Scene::box_room(3),
            &camera_for_width(SIZE.0),
            SIZE,
            &room_trajectory(FRAMES),
        )
        .expect("write the sequence");
        dir
    })
}

/// The camera flags of the test sequence.
fn camera_flags() -> Vec<String> {
    let k = camera_for_width(SIZE.0).pinhole;
    [
        ("--fx", k.fx),
        ("--fy", k.fy),
        ("--cx", k.cx),
        ("--cy", k.cy),
    ]
    .iter()
    .flat_map(|(flag, v)| [flag.to_string(), v.to_string()])
    .collect()
}

/// `vofront ARGS` in `cwd`, with the sequence's camera flags after an `odometry` command.
fn vofront(args: &[&str], cwd: &Path) -> Command {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_vofront"));
    cmd.args(args).current_dir(cwd);
    if args.first() == Some(&"odometry") {
        cmd.args(camera_flags());
    }
    cmd
}

fn run(args: &[&str], cwd: &Path) -> Output {
    vofront(args, cwd).output().expect("run vofront")
}

/// A fresh folder for one test's outputs, beside the shared sequence.
fn out_dir(name: &str) -> PathBuf {
    let dir = sequence().join(name);
    std::fs::remove_dir_all(&dir).ok();
    std::fs::create_dir_all(&dir).expect("output folder");
    dir
}

/// Starts tracking, sends `signal` once [`SIGNAL_AFTER`] frames are in the metrics file, and
/// checks what the stopped run left behind.
#[cfg(unix)]
fn interrupted_run_keeps_every_finished_frame(signal: &str, exit_code: i32) {
    let dir = out_dir(signal);
    let mut child = vofront(
        &[
            "odometry",
            "../seq",
            "--method",
            "feature-rgbd",
            "--out",
            "t.txt",
            "--metrics",
            "m.csv",
        ],
        &dir,
    )
    .stdout(Stdio::piped())
    .stderr(Stdio::piped())
    .spawn()
    .expect("start vofront");
    let metrics = dir.join("m.csv");
    let lines = || {
        std::fs::read_to_string(&metrics)
            .map(|s| s.lines().count())
            .unwrap_or(0)
    };
    let started = Instant::now();
    while lines() <= SIGNAL_AFTER && started.elapsed() < Duration::from_secs(300) {
        std::thread::sleep(Duration::from_millis(5));
    }
    let seen = lines() - 1;
    let kill = Command::new("kill")
        .args([&format!("-{signal}"), &child.id().to_string()])
        .status()
        .expect("run kill");
    assert!(kill.success());
    let status = child.wait().expect("wait for vofront");
    let (mut stdout, mut stderr) = (String::new(), String::new());
    child
        .stdout
        .take()
        .unwrap()
        .read_to_string(&mut stdout)
        .unwrap();
    child
        .stderr
        .take()
        .unwrap()
        .read_to_string(&mut stderr)
        .unwrap();
    assert_eq!(status.code(), Some(exit_code), "{stderr}");
    assert!(stderr.contains("interrupted"), "{stderr}");

    // Every finished frame is in the metrics, in order, and the run stopped early.
    let csv = std::fs::read_to_string(&metrics).unwrap();
    let rows: Vec<Vec<&str>> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').collect())
        .collect();
    assert!(
        rows.len() >= seen && rows.len() < FRAMES,
        "{} rows",
        rows.len()
    );
    for (i, row) in rows.iter().enumerate() {
        assert_eq!(row[0].parse::<usize>().unwrap(), i, "{row:?}");
        assert!(row[1].parse::<f64>().is_ok(), "{row:?}");
    }
    assert!(
        stdout.contains(&format!("frames {}", rows.len())),
        "{stdout}"
    );
    // The trajectory holds exactly the tracked frames, at their timestamps.
    let traj = Trajectory::read_tum(&dir.join("t.txt")).unwrap();
    let tracked: Vec<f64> = rows
        .iter()
        .filter(|r| r[2] == "ok" || r[2] == "reinitialised")
        .map(|r| r[1].parse().unwrap())
        .collect();
    assert_eq!(traj.len(), tracked.len());
    for ((t, _), want) in traj.poses.iter().zip(&tracked) {
        assert!((t - want).abs() < 1e-6);
    }
    let eval = run(
        &[
            "eval",
            "../seq/groundtruth.txt",
            "t.txt",
            "--json",
            "--max-dt",
            "0.02",
        ],
        &dir,
    );
    assert!(
        eval.status.success(),
        "{}",
        String::from_utf8_lossy(&eval.stderr)
    );
    let json: Value = serde_json::from_slice(&eval.stdout).unwrap();
    assert_eq!(json["pairs"], traj.len());
    assert!(json["ate"]["rmse"].as_f64().unwrap() < 0.05, "{json}");
}

#[cfg(unix)]
#[test]
fn sigterm_stops_after_the_frame_in_progress_with_exit_143() {
    interrupted_run_keeps_every_finished_frame("TERM", 143);
}

#[cfg(unix)]
#[test]
fn sigint_stops_after_the_frame_in_progress_with_exit_130() {
    interrupted_run_keeps_every_finished_frame("INT", 130);
}

#[test]
fn unwritable_outputs_fail_before_the_first_frame() {
    let dir = out_dir("unwritable");
    std::fs::write(dir.join("file"), "not a folder").unwrap();
    for flag in ["--out", "--metrics", "--plot"] {
        let out = run(&["odometry", "../seq", flag, "file/x"], &dir);
        assert_eq!(out.status.code(), Some(1), "{flag}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains("file/x") && err.trim().lines().count() == 1,
            "{err}"
        );
        assert!(
            out.stdout.is_empty(),
            "nothing tracked: {}",
            String::from_utf8_lossy(&out.stdout)
        );
    }
    // Missing folders are created, and the defaults go under vofront-out/.
    let out = run(
        &[
            "odometry",
            "../seq",
            "--max-frames",
            "3",
            "--out",
            "a/b/t.txt",
        ],
        &dir,
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(
        Trajectory::read_tum(&dir.join("a/b/t.txt")).unwrap().len(),
        3
    );
    let metrics = std::fs::read_to_string(dir.join("vofront-out/frames.csv")).unwrap();
    assert_eq!(metrics.lines().count(), 4, "header + 3 frames");
}

#[test]
fn json_summary_names_the_run_and_its_outputs() {
    let dir = out_dir("json");
    let out = run(
        &[
            "odometry",
            "../seq",
            "--json",
            "--max-frames",
            "8",
            "--method",
            "feature",
            "--features",
            "600",
        ],
        &dir,
    );
    let json: Value = serde_json::from_slice(&out.stdout).expect("one JSON object");
    assert_eq!(json["method"], "mono", "feature is an alias of mono");
    // Eight frames may be too few for monocular initialisation: then exit 3, said in the JSON.
    let lost = json["lost_for_good"].as_bool().unwrap();
    assert_eq!(out.status.code(), Some(if lost { 3 } else { 0 }), "{json}");
    assert_eq!(json["frames"], 8);
    assert_eq!(json["camera"]["source"], "command-line flags");
    assert_eq!(json["camera"]["fx"], camera_for_width(SIZE.0).pinhole.fx);
    assert_eq!(json["outputs"]["trajectory"], "vofront-out/trajectory.txt");
    let tracked = json["tracked"].as_u64().unwrap();
    assert_eq!(tracked + json["lost"].as_u64().unwrap(), 8);
    assert!(json["fps"].as_f64().unwrap() > 0.0);

    let out = run(
        &["odometry", "../seq", "--json", "--method", "direct"],
        &dir,
    );
    let json: Value = serde_json::from_slice(&out.stdout).expect("one JSON object");
    assert_eq!(json["tracked"], FRAMES);
    assert!(json["ate"]["rmse"].as_f64().unwrap() < 0.01, "{json}");
    assert!(
        json["rpe"]["rotation_deg"]["rmse"].as_f64().is_some(),
        "{json}"
    );
    // An accurate track turns as much as the truth, within its uncertainty.
    let turn = &json["rpe"]["rotation_scale"];
    let (scale, sigma) = (turn["scale"].as_f64(), turn["sigma"].as_f64());
    let (scale, sigma) = (scale.expect("scale"), sigma.expect("sigma"));
    assert!((scale - 1.0).abs() < 4.0 * sigma + 0.01, "{json}");
}

#[test]
fn zero_frames_report_that_nothing_was_tracked() {
    let dir = out_dir("zero");
    let out = run(&["odometry", "../seq", "--max-frames", "0"], &dir);
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("nothing was tracked") && !text.contains("frames/s"),
        "{text}"
    );
    let out = run(&["odometry", "../seq", "--max-frames", "0", "--json"], &dir);
    let json: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["frames"], 0);
    assert!(json["fps"].is_null() && json["ate"].is_null(), "{json}");
}

#[test]
fn a_plain_image_folder_is_timed_by_fps_and_the_bad_rate_is_refused() {
    let dir = out_dir("images");
    let images = dir.join("frames");
    std::fs::create_dir_all(&images).unwrap();
    let mut rgb: Vec<PathBuf> = std::fs::read_dir(sequence().join("seq/rgb"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    rgb.sort();
    for (i, path) in rgb.iter().take(4).enumerate() {
        std::fs::copy(path, images.join(format!("{i:06}.png"))).unwrap();
    }
    let out = run(
        &["odometry", "frames", "--method", "mono", "--fps", "20"],
        &dir,
    );
    // Four frames may be too few for monocular initialisation (exit 3); the timing is the point.
    assert!(
        matches!(out.status.code(), Some(0 | 3)),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let metrics = std::fs::read_to_string(dir.join("vofront-out/frames.csv")).unwrap();
    let stamps: Vec<f64> = metrics
        .lines()
        .skip(1)
        .map(|l| l.split(',').nth(1).unwrap().parse().unwrap())
        .collect();
    assert_eq!(stamps, vec![0.0, 0.05, 0.1, 0.15]);

    let out = run(
        &["odometry", "frames", "--method", "mono", "--fps", "-5"],
        &dir,
    );
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--fps"));
}
