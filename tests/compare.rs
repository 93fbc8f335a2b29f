//! `vofront compare` and `vofront::compare` on a rendered room with exact ground truth: the
//! trackers the registry allows on a TUM RGB-D folder, their scores, the report files, a
//! tracker asked for that cannot run, and a stop before the first frame.

use std::path::PathBuf;
use std::process::{Command, Output};
use std::sync::atomic::AtomicBool;

use serde_json::Value;
use vofront::compare::{compare, plan, CompareConfig};
use vofront::dataset::Dataset;
use vofront::odometry::registry::{Paradigm, TrackerKind};
use vofront::odometry::run::RunControl;
use vofront_fixtures::scene::{default_camera, rescaled_camera, room_trajectory, Scene};
use vofront_fixtures::tum::write_tum_sequence;

const FRAMES: usize = 12;

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("vofront-compare-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A `FRAMES`-frame TUM RGB-D folder of the room, 320x240 (camera: the default at half size).
fn room(name: &str) -> PathBuf {
    let dir = temp_dir(name).join("room");
    let camera = rescaled_camera(&default_camera(), 0.5);
    let poses = room_trajectory(FRAMES);
    write_tum_sequence(&dir, &Scene::box_room(3), &camera, (320, 240), &poses).unwrap();
    dir
}

const CAMERA_FLAGS: [&str; 8] = [
    "--fx", "262.5", "--fy", "262.5", "--cx", "159.75", "--cy", "119.75",
];

fn vofront(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_vofront"))
        .args(args)
        .output()
        .expect("run vofront")
}

/// The names of the registry's trackers that need no stereo rig: what a TUM RGB-D folder
/// allows.
fn rgbd_allowed() -> Vec<&'static str> {
    TrackerKind::ALL
        .iter()
        .filter(|k| !k.needs_right())
        .map(|k| k.name())
        .collect()
}

fn tracker<'a>(report: &'a Value, name: &str) -> &'a Value {
    report["trackers"]
        .as_array()
        .unwrap()
        .iter()
        .find(|t| t["method"] == name)
        .unwrap_or_else(|| panic!("no {name} in {report}"))
}

#[test]
fn compare_runs_every_allowed_tracker_and_writes_the_report_files() {
    let dir = room("cli");
    let out = dir.parent().unwrap().join("out");
    let (data, out_dir) = (dir.to_str().unwrap(), out.to_str().unwrap());
    let mut args = vec!["compare", data, "--json", "--out-dir", out_dir];
    args.extend(CAMERA_FLAGS);
    let run = vofront(&args);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let report: Value = serde_json::from_slice(&run.stdout).unwrap();
    let names: Vec<&str> = report["trackers"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| t["method"].as_str().unwrap())
        .collect();
    assert_eq!(names, rgbd_allowed());
    let skipped: Vec<&str> = report["skipped"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["method"].as_str().unwrap())
        .collect();
    assert_eq!(skipped, ["stereo", "direct-stereo"]);
    assert_eq!(report["frames"], FRAMES);
    assert_eq!(report["ground_truth"], true);
    for name in ["direct", "feature-rgbd"] {
        let t = tracker(&report, name);
        assert!(t["error"].is_null(), "{t}");
        assert_eq!(
            (t["frames"].as_u64(), t["posed"].as_u64()),
            (Some(12), Some(12))
        );
        assert_eq!(t["alignment"], "se3");
        assert!(
            t["ate"]["rmse"].as_f64().unwrap() < 0.01,
            "{name}: {}",
            t["ate"]
        );
        assert_eq!(t["series"].as_array().unwrap().len(), FRAMES);
        let posed = std::fs::read_to_string(out.join(format!("{name}.txt"))).unwrap();
        assert_eq!(posed.lines().count(), 12, "{name}");
    }
    assert_eq!(tracker(&report, "mono")["alignment"], "sim3");
    assert_eq!(tracker(&report, "direct")["residual_unit"], "grey levels");
    assert_eq!(tracker(&report, "feature-rgbd")["residual_unit"], "px");
    let written: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(written, report);
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert_eq!(html.matches("<svg").count(), 3, "three inline figures");
    assert!(html.contains("feature-rgbd") && !html.contains("src=\""));
    std::fs::remove_dir_all(dir.parent().unwrap()).unwrap();
}

#[test]
fn a_tracker_asked_for_that_cannot_run_is_listed_with_its_error() {
    let dir = room("methods");
    let data = dir.to_str().unwrap();
    let mut args = vec![
        "compare",
        data,
        "--methods",
        "stereo,direct",
        "--max-frames",
        "4",
    ];
    args.extend(CAMERA_FLAGS);
    let run = vofront(&args);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let text = String::from_utf8(run.stdout).unwrap();
    assert!(
        text.contains("stereo: failed: ") && text.contains("needs a stereo rig"),
        "{text}"
    );
    let direct = text.lines().find(|l| l.starts_with("direct ")).unwrap();
    assert!(direct.contains("4/4"), "{text}");
    let only_stereo = vofront(&["compare", data, "--methods", "stereo", "--json"]);
    assert_eq!(only_stereo.status.code(), Some(1));
    let report: Value = serde_json::from_slice(&only_stereo.stdout).unwrap();
    assert!(report["trackers"][0]["error"]
        .as_str()
        .unwrap()
        .contains("needs a stereo rig"));
    std::fs::remove_dir_all(dir.parent().unwrap()).unwrap();
}

#[test]
fn the_library_scores_each_frame_and_a_stop_keeps_what_finished() {
    let dir = room("library");
    let dataset = Dataset::open(&dir).unwrap();
    let (kinds, _) = plan(&dataset, None);
    let names: Vec<&str> = kinds.iter().map(|k| k.name()).collect();
    assert_eq!(names, rgbd_allowed());
    let config = CompareConfig {
        methods: Some(vec![TrackerKind::Direct, TrackerKind::FeatureRgbd]),
        camera: Some((rescaled_camera(&default_camera(), 0.5), "test".into())),
        ..CompareConfig::default()
    };
    let report = compare(&dataset, &config, &RunControl::default());
    assert!(!report.interrupted);
    for t in &report.trackers {
        let run = t.run.as_ref().unwrap();
        let want = match t.method {
            TrackerKind::Direct => Paradigm::Direct,
            _ => Paradigm::Feature,
        };
        assert_eq!(t.paradigm, want);
        assert_eq!(run.series.len(), FRAMES);
        assert!(run.tracked <= run.posed && run.posed + run.lost <= run.frames);
        assert!(run.lost_spans.is_empty(), "{:?}", run.lost_spans);
        // Every posed frame has its error after alignment, the first frame is the origin.
        for p in &run.series {
            let e = p.error_m.unwrap();
            assert!(
                (0.0..0.01).contains(&e),
                "{} frame {}: {e}",
                t.method,
                p.index
            );
        }
        let ms = run.ms_median.unwrap();
        assert!(ms > 0.0 && run.wall_ms >= run.ms_mean.unwrap() * FRAMES as f64);
        assert!(run.path_length_m.unwrap() > 0.05 && run.ate_percent.unwrap() < 10.0);
    }
    let stop = AtomicBool::new(true);
    let control = RunControl {
        max_frames: None,
        stop: Some(&stop),
    };
    let stopped = compare(&dataset, &config, &control);
    assert!(stopped.interrupted);
    assert_eq!(
        stopped.trackers.len(),
        1,
        "the trackers after the stop do not run"
    );
    assert_eq!(stopped.trackers[0].run.as_ref().unwrap().frames, 0);
    std::fs::remove_dir_all(dir.parent().unwrap()).unwrap();
}
