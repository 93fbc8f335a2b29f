//! Direct monocular odometry on the shared KITTI clips (and any folder given), beside the
//! monocular feature tracker on the same frames in the same run: one JSON line per sequence
//! and tracker with frames posed (late estimates included), ATE after Sim(3) alignment (metres
//! and percent of the path) and the tracking time per frame (image decoding excluded).
//!
//!     cargo run --release --example direct_mono_kitti -- [--verbose] [--seeds N] [DATASET ...]
//!
//! `--verbose` prints each frame's status, message and scores to stderr.
//!
//! `--seeds N` runs `direct-mono` N times per sequence with the two-view start's RANSAC seed
//! set to `0..N`, with its windowed photometric bundle adjustment and without it
//! (`bundle_window = 0`) on the same frames, and prints one line per seed and variant, then a
//! summary line per variant (median and worst ATE, fewest frames posed, most new maps). The
//! tracker's result hangs on its start; the spread over seeds is the honest figure.
//!
//! Without arguments it reads `../shared/data/kitti_06` and `../shared/data/kitti_01`; a
//! missing folder is reported and skipped. The CLI gives the same trajectory:
//! `vofront odometry DATASET --method direct-mono --out T.txt`.

use std::path::PathBuf;
use std::time::Instant;

use nalgebra::Isometry3;
use vofront::core::lie::{direction_angle_deg, rotation_angle_deg};
use vofront::core::Camera;
use vofront::dataset::{Dataset, Frame};
use vofront::eval::{ate, Alignment, EvalConfig};
use vofront::odometry::direct_mono::{DirectMonoConfig, DirectMonoTracker};
use vofront::odometry::registry::{TrackerKind, TrackerOptions};
use vofront::odometry::{FrameEstimate, TrackStatus, Tracker};
use vofront::robust::median_in_place;
use vofront::trajectory::Trajectory;

fn main() {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let verbose = args.iter().any(|a| a == "--verbose");
    args.retain(|a| a != "--verbose");
    let mut seeds = None;
    if let Some(k) = args.iter().position(|a| a == "--seeds") {
        let n = args.get(k + 1).and_then(|v| v.parse::<u64>().ok());
        let Some(n) = n.filter(|n| *n > 0) else {
            eprintln!("direct_mono_kitti: --seeds needs a positive count");
            std::process::exit(2);
        };
        seeds = Some(n);
        args.drain(k..k + 2);
    }
    let paths: Vec<PathBuf> = if args.is_empty() {
        ["../shared/data/kitti_06", "../shared/data/kitti_01"]
            .iter()
            .map(PathBuf::from)
            .collect()
    } else {
        args.iter().map(PathBuf::from).collect()
    };
    for path in paths {
        let Ok(dataset) = Dataset::open(&path) else {
            eprintln!("{}: not a dataset, skipped", path.display());
            continue;
        };
        let Some(gt) = dataset.ground_truth.clone() else {
            eprintln!("{}: no ground truth, skipped", path.display());
            continue;
        };
        let frames: Vec<_> = (0..dataset.len())
            .filter_map(|i| dataset.load(i).ok())
            .collect();
        let camera = dataset
            .camera
            .unwrap_or_else(vofront::odometry::registry::default_camera);
        let path_m: f64 = gt
            .positions()
            .windows(2)
            .map(|w| (w[1] - w[0]).norm())
            .sum();
        let score = |estimates: &[FrameEstimate]| {
            let mut est = Trajectory::default();
            for (frame, e) in frames.iter().zip(estimates) {
                if e.status != TrackStatus::Lost {
                    est.push(frame.timestamp(), e.pose_wc);
                }
            }
            let cfg = EvalConfig {
                alignment: Alignment::Sim3,
                ..EvalConfig::default()
            };
            let ate_m = ate(&gt, &est, &cfg).map(|a| a.stats.rmse).ok();
            let counts = wrong_ok(frames.as_slice(), estimates, &gt);
            Run {
                posed: est.len(),
                ate_m,
                ok: counts.0,
                wrong_ok: counts.1,
            }
        };
        if let Some(n) = seeds {
            sweep(&path, camera, &frames, n, path_m, &score);
            continue;
        }
        for kind in [TrackerKind::DirectMono, TrackerKind::Mono] {
            let Ok(mut tracker) = kind.build(camera, &TrackerOptions::default()) else {
                continue;
            };
            let mut estimates = Vec::new();
            let start = Instant::now();
            for (i, frame) in frames.iter().enumerate() {
                estimates.push(tracker.track(frame));
                for (back, e) in tracker.revised() {
                    estimates[i - back] = e;
                }
            }
            if verbose {
                for (i, e) in estimates.iter().enumerate() {
                    let q = &e.quality;
                    eprintln!(
                        "{} {i}: {} t {:.3?} inliers {} ratio {:.2} rmse {:.2} kf {} {:.1} ms {}",
                        kind.name(),
                        e.status.as_str(),
                        e.pose_wc.translation.vector.as_slice(),
                        q.inliers,
                        q.inlier_ratio,
                        q.rmse,
                        q.keyframe,
                        q.ms,
                        e.message.as_deref().unwrap_or("")
                    );
                }
            }
            let ms = start.elapsed().as_secs_f64() * 1e3 / frames.len().max(1) as f64;
            let Run { posed, ate_m, .. } = score(&estimates);
            println!(
                "{{\"dataset\": \"{}\", \"method\": \"{}\", \"frames\": {}, \"posed\": {}, \"ate_m\": {}, \"ate_percent\": {}, \"ms_per_frame\": {:.2}}}",
                path.display(),
                kind.name(),
                frames.len(),
                posed,
                ate_m.map_or("null".into(), |a| format!("{a:.4}")),
                ate_m.map_or("null".into(), |a| format!("{:.3}", 100.0 * a / path_m)),
                ms
            );
        }
    }
}

/// The scores of one run.
struct Run {
    /// Frames posed (late estimates included).
    posed: usize,
    /// Sim(3) ATE, metres (`None` when it cannot be computed).
    ate_m: Option<f64>,
    /// Frames flagged `ok`.
    ok: usize,
    /// `ok` frames whose motion from the previous posed frame is wrong: more than 2 degrees
    /// of rotation, 20 degrees of direction (true step over 0.1 m) or a step length off by
    /// more than 2x from its map's scale (the median ratio to the truth over the map's first
    /// ten steps: a monocular map's scale is its own, set where it starts; a new map starts at
    /// `reinitialised`).
    wrong_ok: usize,
}

/// Steps at the start of a map that set its scale (see [`Run::wrong_ok`]).
const SCALE_STEPS: usize = 10;

type Score<'a> = dyn Fn(&[FrameEstimate]) -> Run + 'a;

/// `(ok, wrong_ok)` of a run (see [`Run`]).
fn wrong_ok(frames: &[Frame], estimates: &[FrameEstimate], gt: &Trajectory) -> (usize, usize) {
    let posed = |e: &FrameEstimate| e.status != TrackStatus::Lost;
    // (index, estimated step, true step) for consecutive posed frames with ground truth.
    let steps: Vec<(usize, Isometry3<f64>, Isometry3<f64>)> = (1..estimates.len())
        .filter(|&i| posed(&estimates[i]) && posed(&estimates[i - 1]))
        .filter_map(|i| {
            let g0 = gt.nearest(frames[i - 1].timestamp(), 0.02)?.1;
            let g1 = gt.nearest(frames[i].timestamp(), 0.02)?.1;
            let e = estimates[i - 1].pose_wc.inverse() * estimates[i].pose_wc;
            Some((i, e, g0.inverse() * g1))
        })
        .collect();
    // The map each frame belongs to, and each map's scale: the median ratio of its first
    // `SCALE_STEPS` steps to the truth's (a map's scale is set where it starts).
    let map: Vec<usize> = estimates
        .iter()
        .scan(0, |m, e| {
            *m += usize::from(e.status == TrackStatus::Reinitialised);
            Some(*m)
        })
        .collect();
    let median: Vec<f64> = (0..=map.last().copied().unwrap_or(0))
        .map(|m| {
            let mut ratios: Vec<f64> = steps
                .iter()
                .filter(|(i, _, g)| map[*i] == m && g.translation.vector.norm() > 0.1)
                .map(|(_, e, g)| e.translation.vector.norm() / g.translation.vector.norm())
                .take(SCALE_STEPS)
                .collect();
            median_in_place(&mut ratios).unwrap_or(1.0)
        })
        .collect();
    let wrong = steps
        .iter()
        .filter(|(i, _, _)| estimates[*i].status == TrackStatus::Ok)
        .filter(|(i, e, g)| {
            let rot = rotation_angle_deg(&e.rotation, &g.rotation);
            let (te, tg) = (e.translation.vector, g.translation.vector);
            let moving = tg.norm() > 0.1;
            let ratio = te.norm() / tg.norm() / median[map[*i]];
            rot > 2.0
                || (moving
                    && (direction_angle_deg(&te, &tg) > 20.0 || !(0.5..=2.0).contains(&ratio)))
        })
        .count();
    let ok = estimates
        .iter()
        .filter(|e| e.status == TrackStatus::Ok)
        .count();
    (ok, wrong)
}

/// Tracks `frames` with `tracker`, late estimates put in place.
fn track(tracker: &mut DirectMonoTracker, frames: &[Frame]) -> Vec<FrameEstimate> {
    let mut estimates = Vec::new();
    for (i, frame) in frames.iter().enumerate() {
        estimates.push(tracker.track(frame));
        for (back, e) in tracker.revised() {
            estimates[i - back] = e;
        }
    }
    estimates
}

/// `direct-mono` with and without its bundle adjustment over the RANSAC seeds `0..n`: a line
/// per seed and variant, then a summary line per variant.
fn sweep(
    path: &std::path::Path,
    camera: Camera,
    frames: &[Frame],
    n: u64,
    path_m: f64,
    score: &Score,
) {
    for (variant, bundle_window) in [
        ("bundle", DirectMonoConfig::default().bundle_window),
        ("no_bundle", 0),
    ] {
        let mut ates = Vec::new();
        let mut fewest = usize::MAX;
        let mut most_maps = 0;
        let mut ms = Vec::new();
        let (mut oks, mut wrongs) = (0, 0);
        for seed in 0..n {
            let mut cfg = DirectMonoConfig {
                bundle_window,
                ..DirectMonoConfig::default()
            };
            cfg.relative.ransac.seed = seed;
            let Ok(mut tracker) = DirectMonoTracker::new(camera, cfg) else {
                continue;
            };
            let start = Instant::now();
            let estimates = track(&mut tracker, frames);
            ms.push(start.elapsed().as_secs_f64() * 1e3 / frames.len().max(1) as f64);
            let Run {
                posed,
                ate_m,
                ok,
                wrong_ok,
            } = score(&estimates);
            oks += ok;
            wrongs += wrong_ok;
            let maps = estimates
                .iter()
                .filter(|e| e.status == TrackStatus::Reinitialised)
                .count();
            fewest = fewest.min(posed);
            most_maps = most_maps.max(maps);
            let ate_m = ate_m.unwrap_or(f64::INFINITY);
            ates.push(ate_m);
            println!(
                "{{\"dataset\": \"{}\", \"variant\": \"{variant}\", \"seed\": {seed}, \"posed\": {posed}, \"new_maps\": {maps}, \"ok\": {ok}, \"wrong_ok\": {wrong_ok}, \"ate_m\": {ate_m:.4}, \"ate_percent\": {:.3}}}",
                path.display(),
                100.0 * ate_m / path_m
            );
        }
        let worst = ates.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let median = median_in_place(&mut ates).unwrap_or(f64::NAN);
        let ms = median_in_place(&mut ms).unwrap_or(f64::NAN);
        println!(
            "{{\"dataset\": \"{}\", \"variant\": \"{variant}\", \"summary\": true, \"seeds\": {n}, \"ate_m_median\": {median:.4}, \"ate_percent_median\": {:.3}, \"ate_m_worst\": {worst:.4}, \"posed_fewest\": {fewest}, \"new_maps_most\": {most_maps}, \"ok\": {oks}, \"wrong_ok\": {wrongs}, \"ms_per_frame_median\": {ms:.1}}}",
            path.display(),
            100.0 * median / path_m
        );
    }
}
