//! Monocular odometry benchmark on the shared KITTI clips (and any folder given): tracks each
//! sequence with the default [`MonoTracker`], evaluates against its ground truth and prints one
//! JSON line per sequence: frames tracked, ATE after Sim(3) alignment (metres and percent of
//! the path), scale-free per-frame rotation error (RPE rmse, degrees) and frames per second
//! (tracking only, image decoding excluded), and where a frame's time goes: `orb_ms` (ORB
//! detection and description alone, timed in a separate pass over the same frames) and
//! `track_ms` (the whole tracker per frame, ORB included).
//!
//!     cargo run --release --example mono_kitti -- [DATASET ...]
//!
//! Without arguments it reads `../shared/data/kitti_06` and `../shared/data/kitti_01`; a
//! missing folder is reported and skipped. The OpenCV yardstick is measured in the same run
//! with `opencv_peer.py mono DATASET --out T.txt` and `vofront eval GT T.txt --align sim3`.

use std::path::PathBuf;
use std::time::Instant;

use vofront::dataset::Dataset;
use vofront::eval::{ate, rpe, Alignment, EvalConfig};
use vofront::features::Orb;
use vofront::odometry::mono::{MonoConfig, MonoTracker};
use vofront::odometry::{TrackStatus, Tracker};
use vofront::trajectory::Trajectory;

fn main() {
    let args: Vec<PathBuf> = std::env::args().skip(1).map(PathBuf::from).collect();
    let sets = if args.is_empty() {
        vec![
            PathBuf::from("../shared/data/kitti_06"),
            PathBuf::from("../shared/data/kitti_01"),
        ]
    } else {
        args
    };
    for dir in sets {
        if !dir.exists() {
            eprintln!("mono_kitti: {} not found, skipped", dir.display());
            continue;
        }
        if let Err(e) = bench(&dir) {
            eprintln!("mono_kitti: {}: {e}", dir.display());
        }
    }
}

/// Tracks and scores one sequence, printing its JSON line.
fn bench(dir: &std::path::Path) -> Result<(), String> {
    let dataset = Dataset::open(dir).map_err(|e| e.to_string())?;
    let camera = dataset.camera.ok_or("no calibration in the dataset")?;
    let gt = dataset
        .ground_truth
        .clone()
        .ok_or("no ground truth in the dataset")?;
    // Decode first so that the rate measures tracking alone.
    let frames: Vec<_> = (0..dataset.len())
        .map(|i| dataset.load(i).map_err(|e| e.to_string()))
        .collect::<Result<_, _>>()?;
    let cfg = MonoConfig::default();
    let orb = Orb::new(cfg.orb.clone()).map_err(|e| e.to_string())?;
    let orb_start = Instant::now();
    for frame in &frames {
        orb.detect_and_describe(frame.image())
            .map_err(|e| e.to_string())?;
    }
    let orb_ms = 1e3 * orb_start.elapsed().as_secs_f64() / frames.len().max(1) as f64;
    let mut tracker = MonoTracker::new(camera, cfg).map_err(|e| e.to_string())?;
    let start = Instant::now();
    let mut estimates = Vec::with_capacity(frames.len());
    for frame in &frames {
        estimates.push(tracker.track(frame));
    }
    let seconds = start.elapsed().as_secs_f64();
    // The trajectory as `odometry::run` builds it: every frame that is not lost.
    let mut trajectory = Trajectory::default();
    for (frame, e) in frames.iter().zip(&estimates) {
        if e.status != TrackStatus::Lost {
            trajectory.push(frame.timestamp(), e.pose_wc);
        }
    }
    let cfg = EvalConfig {
        alignment: Alignment::Sim3,
        max_dt: dataset.ground_truth_tolerance,
    };
    let a = ate(&gt, &trajectory, &cfg).map_err(|e| e.to_string())?;
    let r = rpe(&gt, &trajectory, &cfg).map_err(|e| e.to_string())?;
    let path: f64 = gt
        .poses
        .windows(2)
        .map(|w| (w[1].1.translation.vector - w[0].1.translation.vector).norm())
        .sum();
    let keyframes = estimates.iter().filter(|e| e.quality.keyframe).count();
    println!(
        "{{\"dataset\": \"{}\", \"frames\": {}, \"tracked\": {}, \"keyframes\": {}, \"ate_m\": {:.4}, \"path_m\": {:.2}, \"ate_percent\": {:.3}, \"rpe_rot_deg\": {:.4}, \"fps\": {:.1}, \"orb_ms\": {:.1}, \"track_ms\": {:.1}}}",
        dir.display(),
        frames.len(),
        trajectory.len(),
        keyframes,
        a.stats.rmse,
        path,
        100.0 * a.stats.rmse / path.max(1e-9),
        r.rotation_deg.rmse,
        frames.len() as f64 / seconds.max(1e-9),
        orb_ms,
        1e3 * seconds / frames.len().max(1) as f64,
    );
    Ok(())
}
