//! Direct monocular odometry on the shared KITTI clips (and any folder given), beside the
//! monocular feature tracker on the same frames in the same run: one JSON line per sequence
//! and tracker with frames posed (late estimates included), ATE after Sim(3) alignment (metres
//! and percent of the path) and the tracking time per frame (image decoding excluded).
//!
//!     cargo run --release --example direct_mono_kitti -- [--verbose] [DATASET ...]
//!
//! `--verbose` prints each frame's status, message and scores to stderr.
//!
//! Without arguments it reads `../shared/data/kitti_06` and `../shared/data/kitti_01`; a
//! missing folder is reported and skipped. The CLI gives the same trajectory:
//! `vofront odometry DATASET --method direct-mono --out T.txt`.

use std::path::PathBuf;
use std::time::Instant;

use vofront::dataset::Dataset;
use vofront::eval::{ate, Alignment, EvalConfig};
use vofront::odometry::registry::{TrackerKind, TrackerOptions};
use vofront::odometry::TrackStatus;
use vofront::trajectory::Trajectory;

fn main() {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let verbose = args.iter().any(|a| a == "--verbose");
    args.retain(|a| a != "--verbose");
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
            let mut est = Trajectory::default();
            for (frame, e) in frames.iter().zip(&estimates) {
                if e.status != TrackStatus::Lost {
                    est.push(frame.timestamp(), e.pose_wc);
                }
            }
            let cfg = EvalConfig {
                alignment: Alignment::Sim3,
                ..EvalConfig::default()
            };
            let ate_m = ate(&gt, &est, &cfg).map(|a| a.stats.rmse).ok();
            let path_m: f64 = gt
                .positions()
                .windows(2)
                .map(|w| (w[1] - w[0]).norm())
                .sum();
            println!(
                "{{\"dataset\": \"{}\", \"method\": \"{}\", \"frames\": {}, \"posed\": {}, \"ate_m\": {}, \"ate_percent\": {}, \"ms_per_frame\": {:.2}}}",
                path.display(),
                kind.name(),
                frames.len(),
                est.len(),
                ate_m.map_or("null".into(), |a| format!("{a:.4}")),
                ate_m.map_or("null".into(), |a| format!("{:.3}", 100.0 * a / path_m)),
                ms
            );
        }
    }
}
