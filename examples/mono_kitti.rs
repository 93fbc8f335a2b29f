//! Monocular odometry benchmark on the shared KITTI clips (and any folder given): tracks each
//! sequence with the default [`MonoTracker`], evaluates against its ground truth and prints one
//! JSON line per sequence: frames tracked, ATE after Sim(3) alignment (metres and percent of
//! the path), scale-free per-frame rotation error (RPE rmse, degrees) and frames per second
//! (tracking only, image decoding excluded), where a frame's time goes: `orb_ms` (ORB
//! detection and description alone, timed in a separate pass over the same frames) and
//! `track_ms` (the whole tracker per frame, ORB included), and `rot_scale`, the least-squares
//! factor of the estimated over the true per-frame rotations, with its standard deviation
//! `rot_scale_sigma` (`RotationScale`: 1 when the calibration agrees with the ground truth;
//! `null` when the ground truth does not rotate).
//!
//!     cargo run --release --example mono_kitti -- [--seeds N] [--step K] [--reverse] [DATASET ...]
//!
//! `--step K` tracks every K-th frame (frames 0, K, 2K, ...: a K times lower frame rate, the
//! ground truth matched by time as before); `--reverse` plays the frames backwards, last
//! first: frame `i` is given the time `t_first + t_last - t_i` and the ground truth is
//! mirrored the same way, so that the camera drives backwards through the same scene.
//!
//! `--seeds N` tracks each sequence N times, with the RANSAC seeds (two-view and PnP) set to
//! 0..N, prints a line per seed and then a summary line (`"summary": true`: median and worst
//! ATE and RPE, fewest frames tracked, most frames reinitialised: new maps after a loss,
//! `reinitialised` in each seed's line). A monocular tracker's result on a 51-frame clip
//! depends on which samples RANSAC draws; the spread over seeds is the honest figure, one
//! seed's number is a draw from it.
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
use vofront::robust::median_in_place;
use vofront::trajectory::Trajectory;

fn main() {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let mut seeds = None;
    if let Some(k) = args.iter().position(|a| a == "--seeds") {
        let n = args.get(k + 1).and_then(|v| v.parse::<u64>().ok());
        let Some(n) = n.filter(|n| *n > 0) else {
            eprintln!("mono_kitti: --seeds needs a positive count");
            std::process::exit(2);
        };
        seeds = Some(n);
        args.drain(k..k + 2);
    }
    let mut order = Order {
        step: 1,
        reverse: false,
    };
    if let Some(k) = args.iter().position(|a| a == "--step") {
        let n = args.get(k + 1).and_then(|v| v.parse::<usize>().ok());
        let Some(n) = n.filter(|n| *n > 0) else {
            eprintln!("mono_kitti: --step needs a positive count");
            std::process::exit(2);
        };
        order.step = n;
        args.drain(k..k + 2);
    }
    if let Some(k) = args.iter().position(|a| a == "--reverse") {
        order.reverse = true;
        args.remove(k);
    }
    let args: Vec<PathBuf> = args.into_iter().map(PathBuf::from).collect();
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
        let result = match seeds {
            None => bench(&dir, None, order).map(|_| ()),
            Some(n) => sweep(&dir, n, order),
        };
        if let Err(e) = result {
            eprintln!("mono_kitti: {}: {e}", dir.display());
        }
    }
}

/// Which frames are tracked, in which order (`--step`, `--reverse`).
#[derive(Debug, Clone, Copy)]
struct Order {
    step: usize,
    reverse: bool,
}

impl Order {
    /// The frame indices of a dataset of `n` frames, in tracking order.
    fn indices(self, n: usize) -> Vec<usize> {
        let mut indices: Vec<usize> = (0..n).step_by(self.step).collect();
        if self.reverse {
            indices.reverse();
        }
        indices
    }
}

/// One run's scores.
struct Score {
    tracked: usize,
    ate_m: f64,
    rpe_rot_deg: f64,
    rot_scale: Option<f64>,
    reinitialised: usize,
}

/// Runs `bench` with the RANSAC seeds `0..n` and prints the summary line.
fn sweep(dir: &std::path::Path, n: u64, order: Order) -> Result<(), String> {
    let scores: Vec<Score> = (0..n)
        .map(|seed| bench(dir, Some(seed), order))
        .collect::<Result<_, _>>()?;
    let median = |mut v: Vec<f64>| median_in_place(&mut v).unwrap_or(f64::NAN);
    let worst = |v: &[f64]| v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let ate: Vec<f64> = scores.iter().map(|s| s.ate_m).collect();
    let rot: Vec<f64> = scores.iter().map(|s| s.rpe_rot_deg).collect();
    let rot_scale: Vec<f64> = scores.iter().filter_map(|s| s.rot_scale).collect();
    let rot_scale = (!rot_scale.is_empty()).then(|| format!("{:.4}", median(rot_scale)));
    println!(
        "{{\"dataset\": \"{}\", \"summary\": true, \"seeds\": {n}, \"ate_m_median\": {:.4}, \"ate_m_worst\": {:.4}, \"rpe_rot_deg_median\": {:.4}, \"rpe_rot_deg_worst\": {:.4}, \"tracked_fewest\": {}, \"reinitialised_most\": {}, \"rot_scale_median\": {}}}",
        dir.display(),
        median(ate.clone()),
        worst(&ate),
        median(rot.clone()),
        worst(&rot),
        scores.iter().map(|s| s.tracked).min().unwrap_or(0),
        scores.iter().map(|s| s.reinitialised).max().unwrap_or(0),
        rot_scale.as_deref().unwrap_or("null"),
    );
    Ok(())
}

/// Tracks and scores one sequence (with the RANSAC seeds set to `seed` if given), printing
/// its JSON line.
fn bench(dir: &std::path::Path, seed: Option<u64>, order: Order) -> Result<Score, String> {
    let dataset = Dataset::open(dir).map_err(|e| e.to_string())?;
    let camera = dataset.camera.ok_or("no calibration in the dataset")?;
    let mut gt = dataset
        .ground_truth
        .clone()
        .ok_or("no ground truth in the dataset")?;
    // Played backwards, time is mirrored about the middle of the clip: t' = t_first + t_last - t.
    let times = dataset.frames.iter().map(|f| f.timestamp);
    let mirror =
        times.clone().fold(f64::INFINITY, f64::min) + times.fold(f64::NEG_INFINITY, f64::max);
    if order.reverse {
        gt = Trajectory::new(
            gt.poses
                .iter()
                .rev()
                .map(|(t, p)| (mirror - t, *p))
                .collect(),
        );
    }
    // Decode first so that the rate measures tracking alone.
    let frames: Vec<_> = order
        .indices(dataset.len())
        .into_iter()
        .map(|i| {
            let frame = dataset.load(i).map_err(|e| e.to_string())?;
            if order.reverse {
                let t = mirror - frame.timestamp();
                frame.with_timestamp(t).map_err(|e| e.to_string())
            } else {
                Ok(frame)
            }
        })
        .collect::<Result<_, _>>()?;
    let mut cfg = MonoConfig::default();
    if let Some(seed) = seed {
        cfg.relative.ransac.seed = seed;
        cfg.pnp.ransac.seed = seed;
    }
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
        // Frames an initialisation waited through are located late (`Tracker::revised`).
        let newest = estimates.len() - 1;
        for (back, e) in tracker.revised() {
            estimates[newest - back] = e;
        }
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
    let rot_scale = r.rotation_scale;
    let keyframes = estimates.iter().filter(|e| e.quality.keyframe).count();
    let reinitialised = estimates
        .iter()
        .filter(|e| e.status == TrackStatus::Reinitialised)
        .count();
    println!(
        "{{\"dataset\": \"{}\", \"seed\": {}, \"frames\": {}, \"tracked\": {}, \"keyframes\": {}, \"reinitialised\": {}, \"ate_m\": {:.4}, \"path_m\": {:.2}, \"ate_percent\": {:.3}, \"rpe_rot_deg\": {:.4}, \"fps\": {:.1}, \"orb_ms\": {:.1}, \"track_ms\": {:.1}, \"rot_scale\": {}, \"rot_scale_sigma\": {}}}",
        dir.display(),
        seed.map_or_else(|| "null".into(), |s| s.to_string()),
        frames.len(),
        trajectory.len(),
        keyframes,
        reinitialised,
        a.stats.rmse,
        path,
        100.0 * a.stats.rmse / path.max(1e-9),
        r.rotation_deg.rmse,
        frames.len() as f64 / seconds.max(1e-9),
        orb_ms,
        1e3 * seconds / frames.len().max(1) as f64,
        rot_scale.map_or_else(|| "null".into(), |k| format!("{:.4}", k.scale)),
        rot_scale.map_or_else(|| "null".into(), |k| format!("{:.4}", k.sigma)),
    );
    Ok(Score {
        tracked: trajectory.len(),
        ate_m: a.stats.rmse,
        rpe_rot_deg: r.rotation_deg.rmse,
        rot_scale: rot_scale.map(|k| k.scale),
        reinitialised,
    })
}
