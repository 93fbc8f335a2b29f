//! evo's trajectory formats (TUM, KITTI, EuRoC): detection, reading, index pairing, results
//! equal to `evo_ape kitti` / `evo_ape euroc` / `evo_rpe`, and `odometry --out-format kitti`.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use vofront::eval::{ate, rpe, Alignment, EvalConfig, Stats};
use vofront::fixtures::scene::{default_camera, room_trajectory, Scene};
use vofront::fixtures::tum::write_tum_sequence;
use vofront::trajectory::{
    pair_untimed, Trajectory, TrajectoryError, TrajectoryFile, TrajectoryFormat,
};

/// Agreement required with evo's statistics (the bound).
const EVO_TOLERANCE: f64 = 1e-6;

/// evo's statistics `[rmse, mean, median, std, min, max, sse]` and count.
struct EvoStats([f64; 7], usize);

// evo v1.38.1 (the `evo` package of ../shared/tools/peers/setup.sh) on the files written by
// tests/data/make_evo_formats.py, statistics from `stats.json` of `--save_results`, counts
// from `error_array.npy`:
//   evo_ape kitti evo_gt.kitti evo_est_all.kitti [--align [--correct_scale]] --no_warnings
//   evo_rpe kitti evo_gt.kitti evo_est_all.kitti --delta 1 --delta_unit f
//           --pose_relation {trans_part, angle_deg} --no_warnings
// and the same with `euroc evo_gt_euroc.csv evo_est.txt` (the EuRoC ground truth against the
// TUM estimate of tests/eval.rs; evo associated 100 poses).
/// `[none, se3, sim3]` ATE, then RPE translation and angle, of the KITTI pair.
const KITTI: [EvoStats; 5] = [
    EvoStats(
        [
            2.415642743592311,
            2.414914374813884,
            2.40312381190055,
            0.05931632985486584,
            2.3392596723750803,
            2.561629070031819,
            700.2395837604224,
        ],
        120,
    ),
    EvoStats(
        [
            0.06379509984447027,
            0.0598098072173169,
            0.05547997538628694,
            0.022194632792486534,
            0.025781596133063467,
            0.1269569115080866,
            0.4883777716999117,
        ],
        120,
    ),
    EvoStats(
        [
            0.012232470451155813,
            0.01191224154885808,
            0.012883917356158799,
            0.00278061766880299,
            0.005324689781992984,
            0.01587083831606684,
            0.017956000000608013,
        ],
        120,
    ),
    EvoStats(
        [
            0.01159621362770542,
            0.01112169223326248,
            0.01126885832679408,
            0.003283311189633104,
            0.0031104321573351347,
            0.01935705906117375,
            0.016002188289426327,
        ],
        119,
    ),
    EvoStats(
        [
            0.877385241875439,
            0.8478321206359671,
            0.8674711147371666,
            0.22579981815480155,
            0.30380573621283774,
            1.2390156411477822,
            91.60677865663789,
        ],
        119,
    ),
];
/// The same five for the EuRoC ground truth against the TUM estimate.
const EUROC: [EvoStats; 5] = [
    EvoStats(
        [
            2.4170259051732534,
            2.4162846945004848,
            2.3998056735512066,
            0.05985400071244417,
            2.3412828046692837,
            2.559693756250776,
            584.2014226278586,
        ],
        100,
    ),
    EvoStats(
        [
            0.0643461137013655,
            0.06037422913518021,
            0.05718914605159607,
            0.022257016978962253,
            0.02387841147310822,
            0.12826305223534493,
            0.4140422348469058,
        ],
        100,
    ),
    EvoStats(
        [
            0.012286853033885638,
            0.011891923435773643,
            0.012482023704713355,
            0.0030901317890993365,
            0.0008465519676895215,
            0.01755731617179336,
            0.015096675747630468,
        ],
        100,
    ),
    EvoStats(
        [
            0.013566660784055105,
            0.013021241035735537,
            0.013397749226226541,
            0.0038080922676447322,
            0.003291226967751007,
            0.02531427726193943,
            0.01822137419813225,
        ],
        99,
    ),
    EvoStats(
        [
            0.8214581792629835,
            0.784540357402654,
            0.8258440162450527,
            0.24349531388626725,
            0.2605301039788813,
            1.1307554473823935,
            66.80456048752754,
        ],
        99,
    ),
];

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name)
}

/// Reads a test file, its format detected.
fn read(name: &str, times: Option<&str>) -> TrajectoryFile {
    let times = times.map(data);
    TrajectoryFile::read(&data(name), None, times.as_deref()).expect(name)
}

/// Largest |ours - evo| over the seven statistics; also checks the count.
fn max_diff(ours: &Stats, evo: &EvoStats) -> f64 {
    assert_eq!(ours.count, evo.1, "number of errors");
    let o = [
        ours.rmse,
        ours.mean,
        ours.median,
        ours.std,
        ours.min,
        ours.max,
        ours.sse,
    ];
    o.iter()
        .zip(evo.0)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max)
}

/// ATE (none, se3, sim3) and RPE (translation, angle) of `gt`, `est` against evo's five.
fn assert_matches_evo(gt: &Trajectory, est: &Trajectory, evo: &[EvoStats; 5], what: &str) {
    for (alignment, evo) in [Alignment::None, Alignment::Se3, Alignment::Sim3]
        .into_iter()
        .zip(evo)
    {
        let cfg = EvalConfig {
            alignment,
            ..EvalConfig::default()
        };
        let d = max_diff(&ate(gt, est, &cfg).expect("ate").stats, evo);
        assert!(d < EVO_TOLERANCE, "{what} ATE {alignment:?}: {d}");
    }
    let r = rpe(gt, est, &EvalConfig::default()).expect("rpe");
    let d = max_diff(&r.translation, &evo[3]).max(max_diff(&r.rotation_deg, &evo[4]));
    assert!(d < EVO_TOLERANCE, "{what} RPE: {d}");
}

#[test]
fn kitti_pair_matches_evo_ape_kitti_by_index() {
    let (gt, est) = (read("evo_gt.kitti", None), read("evo_est_all.kitti", None));
    assert_eq!((gt.format, gt.timed), (TrajectoryFormat::Kitti, false));
    let (gt, est) = pair_untimed(gt, est).expect("same length");
    assert_matches_evo(&gt, &est, &KITTI, "kitti");
}

#[test]
fn euroc_reference_matches_evo_ape_euroc() {
    let gt = read("evo_gt_euroc.csv", None);
    assert_eq!((gt.format, gt.timed), (TrajectoryFormat::Euroc, true));
    // Nanoseconds become seconds.
    assert!((gt.trajectory.poses[1].0 - 1000.033333).abs() < 1e-9);
    let est = read("evo_est.txt", None);
    assert_eq!(est.format, TrajectoryFormat::Tum);
    let (gt, est) = pair_untimed(gt, est).expect("timed");
    assert_matches_evo(&gt, &est, &EUROC, "euroc");
}

#[test]
fn kitti_with_times_is_associated_by_time_like_tum() {
    // evo_gt.kitti with its stamps is evo_gt.txt: the EuRoC numbers (same poses) come back.
    let gt = read("evo_gt.kitti", Some("evo_gt.times"));
    assert!(gt.timed);
    let (gt, est) = pair_untimed(gt, read("evo_est.txt", None)).expect("timed");
    for (alignment, evo) in [Alignment::None, Alignment::Se3, Alignment::Sim3]
        .into_iter()
        .zip(&EUROC)
    {
        let cfg = EvalConfig {
            alignment,
            ..EvalConfig::default()
        };
        let d = max_diff(&ate(&gt, &est, &cfg).expect("ate").stats, evo);
        assert!(d < EVO_TOLERANCE, "{alignment:?}: {d}");
    }
}

#[test]
fn an_untimed_kitti_file_takes_the_stamps_of_the_other_or_is_refused() {
    let est_kitti = read("evo_est_all.kitti", None);
    let gt_tum = read("evo_gt.kitti", Some("evo_gt.times"));
    // KITTI estimate against a timed reference of the same length: matched by index.
    let (gt, est) = pair_untimed(gt_tum.clone(), est_kitti.clone()).expect("same length");
    assert_eq!(gt.timestamps(), est.timestamps());
    assert_matches_evo(&gt, &est, &KITTI, "timed gt, kitti est");
    // And the other way round.
    let (gt, est) = pair_untimed(read("evo_gt.kitti", None), read("evo_est_all.kitti", None))
        .expect("same length");
    assert_eq!(gt.timestamps(), (0..120).map(f64::from).collect::<Vec<_>>());
    assert_eq!(est.timestamps(), gt.timestamps());
    // Different lengths cannot be matched by index.
    match pair_untimed(read("evo_gt.kitti", None), read("evo_est.txt", None)) {
        Err(TrajectoryError::IndexMismatch {
            reference: 120,
            estimate: 103,
        }) => {}
        other => panic!("{other:?}"),
    }
}

#[test]
fn formats_are_detected_from_the_content() {
    let detect = TrajectoryFormat::detect;
    assert_eq!(
        detect("# t x\n1.0 0 0 0 0 0 0 1\n"),
        Some(TrajectoryFormat::Tum)
    );
    assert_eq!(detect("1,0,0,0,0,0,0,1\n"), Some(TrajectoryFormat::Tum));
    assert_eq!(
        detect("1 0 0 0 0 1 0 0 0 0 1 0\n"),
        Some(TrajectoryFormat::Kitti)
    );
    assert_eq!(
        detect("1403636579763555584,1,2,3,1,0,0,0,0.1,0.2\n"),
        Some(TrajectoryFormat::Euroc)
    );
    assert_eq!(
        detect("#timestamp, p_RS_R_x [m], p_RS_R_y [m]\n10,1,2,3,1,0,0,0\n"),
        Some(TrajectoryFormat::Euroc)
    );
    // Nanosecond stamps without commas stay TUM, as evo reads such files.
    assert_eq!(
        detect("1403636579763555584 1 2 3 0 0 0 1\n"),
        Some(TrajectoryFormat::Tum)
    );
    assert_eq!(detect("1 2 3 4 5\n"), None);
    assert_eq!(detect("# nothing\n"), None);
    assert_eq!("KITTI".parse(), Ok(TrajectoryFormat::Kitti));
    assert!("g2o".parse::<TrajectoryFormat>().is_err());
}

#[test]
fn times_are_refused_for_formats_with_their_own_stamps() {
    let r = TrajectoryFile::read(&data("evo_est.txt"), None, Some(&data("evo_gt.times")));
    assert!(
        matches!(r, Err(TrajectoryError::TimesNotKitti { format: "tum", .. })),
        "{r:?}"
    );
    // A forced format reads the content as that format.
    let r = TrajectoryFile::read(&data("evo_gt.kitti"), Some(TrajectoryFormat::Tum), None);
    assert!(
        matches!(r, Err(TrajectoryError::Parse { line: 1, .. })),
        "{r:?}"
    );
    // A times file must hold one stamp per line.
    let r = TrajectoryFile::read(&data("evo_est_all.kitti"), None, Some(&data("evo_est.txt")));
    assert!(matches!(r, Err(TrajectoryError::Parse { .. })), "{r:?}");
}

#[test]
fn kitti_text_round_trips() {
    let traj = Trajectory::new(
        room_trajectory(20)
            .into_iter()
            .enumerate()
            .map(|(i, p)| (i as f64 * 0.05, p))
            .collect(),
    );
    let dir = std::env::temp_dir().join(format!("vofront-kitti-rt-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    traj.write_kitti(&dir.join("p.txt")).expect("write");
    std::fs::write(dir.join("t.txt"), traj.to_times_string()).expect("times");
    let back = Trajectory::read_kitti(&dir.join("p.txt"), Some(&dir.join("t.txt"))).expect("read");
    assert_eq!(back.len(), traj.len());
    for ((t1, p1), (t2, p2)) in back.poses.iter().zip(&traj.poses) {
        assert!((t1 - t2).abs() < 1e-9);
        let e = p1.inverse() * p2;
        assert!(e.translation.vector.norm() < 1e-8 && e.rotation.angle() < 1e-8);
    }
    std::fs::remove_dir_all(&dir).ok();
}

fn vofront(args: &[&str], dir: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_vofront"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("run vofront")
}

fn json_of(out: &Output) -> serde_json::Value {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("one JSON object")
}

#[test]
fn eval_command_reads_kitti_and_euroc_as_evo() {
    let dir = data("");
    let json = json_of(&vofront(
        &["eval", "evo_gt_euroc.csv", "evo_est.txt", "--json"],
        &dir,
    ));
    let rmse = json["ate"]["rmse"].as_f64().expect("rmse");
    assert!((rmse - EUROC[1].0[0]).abs() < EVO_TOLERANCE, "{json}");
    assert_eq!(json["pairs"], 100);
    let json = json_of(&vofront(
        &[
            "eval",
            "evo_gt.kitti",
            "evo_est_all.kitti",
            "--align",
            "sim3",
            "--json",
        ],
        &dir,
    ));
    let rmse = json["ate"]["rmse"].as_f64().expect("rmse");
    assert!((rmse - KITTI[2].0[0]).abs() < EVO_TOLERANCE, "{json}");
    // With the reference's times, the KITTI ground truth meets the TUM estimate by time.
    let json = json_of(&vofront(
        &[
            "eval",
            "evo_gt.kitti",
            "evo_est.txt",
            "--times",
            "evo_gt.times",
            "--json",
        ],
        &dir,
    ));
    assert_eq!(json["pairs"], 100);
    // Without them, the lengths differ: a clear error.
    let out = vofront(&["eval", "evo_gt.kitti", "evo_est.txt"], &dir);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("matched by index"),
        "{err}"
    );
    // A forced format is obeyed.
    let out = vofront(
        &[
            "eval",
            "evo_gt.kitti",
            "evo_est_all.kitti",
            "--format",
            "tum",
        ],
        &dir,
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("expected 8 fields"),
        "{err}"
    );
}

#[test]
fn odometry_writes_kitti_poses_with_their_times() {
    let dir = std::env::temp_dir().join(format!("vofront-kitti-out-{}", std::process::id()));
    std::fs::remove_dir_all(&dir).ok();
    write_tum_sequence(
        &dir.join("seq"),
        &Scene::box_room(1),
        &default_camera(),
        (640, 480),
        &room_trajectory(6),
    )
    .expect("render");
    let run = |format: &str, out: &str| {
        json_of(&vofront(
            &[
                "odometry",
                "seq",
                "--out-format",
                format,
                "--out",
                out,
                "--metrics",
                "m.csv",
                "--json",
            ],
            &dir,
        ))
    };
    run("tum", "t.txt");
    run("kitti", "k.txt");
    let tum = Trajectory::read_tum(&dir.join("t.txt")).expect("tum");
    let kitti = TrajectoryFile::read(&dir.join("k.txt"), None, Some(&dir.join("k.txt.times")))
        .expect("kitti");
    assert_eq!(kitti.format, TrajectoryFormat::Kitti);
    assert_eq!((tum.len(), kitti.trajectory.len()), (6, 6));
    for ((t1, p1), (t2, p2)) in tum.poses.iter().zip(&kitti.trajectory.poses) {
        assert!((t1 - t2).abs() < 1e-9, "{t1} {t2}");
        assert!((p1.inverse() * p2).translation.vector.norm() < 1e-8);
    }
    // The KITTI output evaluates like the TUM one.
    let ate_of = |args: &[&str]| {
        let mut all = vec!["eval", "seq/groundtruth.txt"];
        all.extend_from_slice(args);
        all.push("--json");
        json_of(&vofront(&all, &dir))["ate"]["rmse"]
            .as_f64()
            .expect("rmse")
    };
    let (a, b) = (
        ate_of(&["t.txt"]),
        ate_of(&["k.txt", "--est-times", "k.txt.times"]),
    );
    assert!((a - b).abs() < 1e-6, "{a} {b}");
    std::fs::remove_dir_all(&dir).ok();
}
