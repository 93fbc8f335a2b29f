//! Where each paradigm wins: every tracker the registry allows on a TUM RGB-D folder, run
//! through `vofront::compare` on the rendered challenges of `vofront_fixtures::challenges`
//! (exposure jumps, motion blur, low texture with strong gradients, a repeated pattern;
//! 320x240, 30 frames, exact poses). Each test states what the trackers do there, as
//! measured (`cargo test --release --test challenges -- --nocapture` prints the tables): the
//! RGB-D direct tracker is the most accurate on blur, low texture and the repeated pattern,
//! where the feature trackers drift (feature RGB-D ten times its error on the repeated
//! pattern, the monocular one forty times, though it keeps every frame); through the exposure jumps the feature
//! trackers keep every frame without a break, while the direct tracker restarts at some of
//! the jumps. On one camera, the direct monocular tracker keeps every frame through the
//! jumps without a break (retried from the gain of the mean grey levels) and through the
//! blur; it loses frames on low texture and drifts on the repeated pattern (the compare
//! tables show it).

use std::path::PathBuf;

use vofront::compare::{compare, table::table, CompareConfig, CompareReport, TrackerRun};
use vofront::dataset::Dataset;
use vofront::odometry::registry::TrackerKind;
use vofront::odometry::run::RunControl;
use vofront_fixtures::challenges::{challenge_camera, write_challenge, Challenge, EXPOSURE_BLOCK};

const FRAMES: usize = 30;

/// The comparison of every allowed tracker on `FRAMES` frames of `challenge` (the table is
/// printed, to be read with `--nocapture`).
fn compare_on(challenge: Challenge) -> CompareReport {
    let dir: PathBuf = std::env::temp_dir().join(format!(
        "vofront-challenge-{}-{}",
        challenge.name(),
        std::process::id()
    ));
    write_challenge(&dir, challenge, FRAMES).unwrap();
    let dataset = Dataset::open(&dir).unwrap();
    let config = CompareConfig {
        camera: Some((challenge_camera(), "the rendering camera".into())),
        ..CompareConfig::default()
    };
    let report = compare(&dataset, &config, &RunControl::default());
    println!("{}\n{}", challenge.name(), table(&report));
    std::fs::remove_dir_all(&dir).unwrap();
    report
}

/// The run of `kind` in `report`.
fn run(report: &CompareReport, kind: TrackerKind) -> &TrackerRun {
    report
        .trackers
        .iter()
        .find(|t| t.method == kind)
        .and_then(|t| t.run.as_ref())
        .unwrap_or_else(|| panic!("{kind} did not run"))
}

/// ATE RMSE of `run`, metres.
fn ate(run: &TrackerRun) -> f64 {
    match &run.ate {
        Some(vofront::report::Entry::Ok(a)) => a.stats.rmse,
        other => panic!("no ATE: {other:?}"),
    }
}

/// Every tracker the registry allows on a TUM RGB-D folder ran on every frame.
fn assert_every_allowed_tracker_ran(report: &CompareReport) {
    let names: Vec<&str> = report.trackers.iter().map(|t| t.method.name()).collect();
    let want: Vec<&str> = TrackerKind::ALL
        .iter()
        .filter(|k| !k.needs_right())
        .map(|k| k.name())
        .collect();
    assert_eq!(names, want);
    for t in &report.trackers {
        let r = t.run.as_ref().unwrap();
        assert_eq!((r.frames, r.series.len()), (FRAMES, FRAMES), "{}", t.method);
    }
}

#[test]
fn through_exposure_jumps_direct_restarts_and_the_others_keep_going() {
    let report = compare_on(Challenge::ExposureJumps);
    assert_every_allowed_tracker_ran(&report);
    for kind in [TrackerKind::FeatureRgbd, TrackerKind::Mono] {
        let r = run(&report, kind);
        assert_eq!((r.posed, r.segment_breaks), (FRAMES, 0), "{kind}");
    }
    assert!(ate(run(&report, TrackerKind::FeatureRgbd)) < 0.005);
    // Direct poses every frame, but restarts (a new keyframe at the motion model's guess)
    // at some of the 2x jumps, and only there.
    let direct = run(&report, TrackerKind::Direct);
    assert_eq!(direct.posed, FRAMES);
    assert!(direct.segment_breaks > 0);
    for p in direct.series.iter().filter(|p| p.status == "reinitialised") {
        assert_eq!(p.index % EXPOSURE_BLOCK, 0, "restart at frame {}", p.index);
    }
    assert!(ate(direct) < 0.01);
    // The direct monocular tracker poses every frame through the jumps, in one map.
    let mono_direct = run(&report, TrackerKind::DirectMono);
    assert_eq!((mono_direct.posed, mono_direct.segment_breaks), (FRAMES, 0));
    let percent = mono_direct.ate_percent.unwrap();
    assert!(percent < 1.0, "direct-mono {percent} % of the path");
}

#[test]
fn through_motion_blur_direct_is_the_most_accurate() {
    let report = compare_on(Challenge::MotionBlur);
    assert_every_allowed_tracker_ran(&report);
    let direct = ate(run(&report, TrackerKind::Direct));
    let feature = ate(run(&report, TrackerKind::FeatureRgbd));
    assert!(
        direct < feature,
        "direct {direct} m, feature-rgbd {feature} m"
    );
    for kind in [
        TrackerKind::Direct,
        TrackerKind::FeatureRgbd,
        TrackerKind::Mono,
    ] {
        assert_eq!(run(&report, kind).posed, FRAMES, "{kind}");
    }
}

#[test]
fn on_low_texture_with_strong_gradients_direct_is_the_most_accurate() {
    let report = compare_on(Challenge::LowTexture);
    assert_every_allowed_tracker_ran(&report);
    let direct = ate(run(&report, TrackerKind::Direct));
    let feature = ate(run(&report, TrackerKind::FeatureRgbd));
    assert!(
        direct < feature,
        "direct {direct} m, feature-rgbd {feature} m"
    );
    assert!(direct < 0.005);
    assert_eq!(run(&report, TrackerKind::FeatureRgbd).posed, FRAMES);
}

#[test]
fn on_a_repeated_pattern_the_feature_trackers_drift() {
    let report = compare_on(Challenge::RepeatedPattern);
    assert_every_allowed_tracker_ran(&report);
    let direct = ate(run(&report, TrackerKind::Direct));
    let feature = ate(run(&report, TrackerKind::FeatureRgbd));
    assert!(direct < 0.005, "{direct}");
    assert!(
        feature > 3.0 * direct,
        "direct {direct} m, feature-rgbd {feature} m"
    );
    let mono = run(&report, TrackerKind::Mono);
    let direct_percent = run(&report, TrackerKind::Direct).ate_percent.unwrap();
    assert!(
        mono.ate_percent.unwrap() > 10.0 * direct_percent,
        "mono {:?} %, direct {direct_percent} %",
        mono.ate_percent
    );
}
