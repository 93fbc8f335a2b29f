//! How noisy are the stereo matcher's disparities on real frames, and how long does the
//! camera's step look to the near points, against the ground-truth motion?
//!
//! For frames `i` and `j = i + gap` of a rectified stereo clip with ground truth: ORB on all
//! four images, [`match_stereo`] in both frames, the left features of `i` matched to those of
//! `j` by descriptor (ratio 0.8) and kept when frame `i`'s stereo point, moved by the true
//! motion `T_ji`, lands within 3 px of its match. The point's disparity predicted in frame `j`,
//! `d_pred = f b / Z_j`, against the one measured there, `d_j`:
//!
//! `r = d_j - d_pred`, `Var(r) = s_j^2 + (d_pred / d_i)^4 s_i^2`,
//!
//! where `s = sigma_px * noise_scale` is the model's disparity noise (the stereo tracker's
//! `KEYPOINT_QUANTISATION_PX` at level 0). A step error `delta` moves `d_pred` by
//! `d_pred^2 delta / (f b)`: for a point 40 m or more away on KITTI, 5% of a 1 m step is at
//! most 0.012 px, so the far bins' spread measures the matcher, not the ground truth.
//! Printed per disparity bin: the count, the median `r` (a bias), its robust spread
//! (1.4826 MAD), the median and robust spread of `r / sqrt(Var(r))` (1 when the model's
//! noise is right), the share beyond 3 of the model's sigmas, and the median step excess
//! `r f b / d_pred^2 / |t_ji|`: a camera that moved `delta` metres further along its axis than
//! the ground truth says gives `r = d_pred^2 delta / (f b)`, so near points (large `d`, whose
//! stereo depth is accurate) measure the ground truth's step length.
//!
//!     cargo run --release --example stereo_noise -- [--gap K] [DATASET ...]
//!
//! Without datasets it reads `../shared/data/kitti_06` and `../shared/data/kitti_01`; a
//! missing folder is reported and skipped.

use std::path::PathBuf;

use vofront::dataset::Dataset;
use vofront::features::{knn2, match_stereo, Features, Orb, OrbConfig, StereoConfig, StereoMatch};
use vofront::odometry::mono::KEYPOINT_QUANTISATION_PX;
use vofront::robust::{mad_sigma, median_in_place};

/// Disparity bins, pixels (`[lo, hi)`).
const BINS: [(f32, f32); 6] = [
    (1.0, 5.0),
    (5.0, 10.0),
    (10.0, 20.0),
    (20.0, 40.0),
    (40.0, 80.0),
    (80.0, 400.0),
];

/// One temporal match: its frame-`j` disparity, the residual, the normalised residual and the
/// step excess it implies.
struct Sample {
    disparity: f32,
    residual: f64,
    normalised: f64,
    step_excess: f64,
}

/// A frame's left features and stereo matches indexed by left feature.
struct StereoFrame {
    features: Features,
    by_left: Vec<Option<StereoMatch>>,
}

fn stereo_frame(
    orb: &Orb,
    data: &Dataset,
    index: usize,
) -> Result<StereoFrame, Box<dyn std::error::Error>> {
    let frame = data.load_stereo(index)?;
    let right_image = frame.right().ok_or("no right image")?;
    let features = orb.detect_and_describe(frame.image())?;
    let right = orb.detect_and_describe(right_image)?;
    let matches = match_stereo(
        &features,
        &right,
        frame.image(),
        right_image,
        &StereoConfig::default(),
    )?;
    let mut by_left = vec![None; features.len()];
    for m in matches {
        by_left[m.left as usize] = Some(m);
    }
    Ok(StereoFrame { features, by_left })
}

/// The median of `values` (NaN when empty).
fn median(values: &[f64]) -> f64 {
    median_in_place(&mut values.to_vec()).unwrap_or(f64::NAN)
}

fn measure(root: &PathBuf, gap: usize) -> Result<(), Box<dyn std::error::Error>> {
    let data = Dataset::open(root)?;
    let rig = data.rig.ok_or("no camera rig")?;
    let baseline = rig.baseline().ok_or("not a stereo rig")?;
    let k = rig.left().pinhole;
    let fb = k.fx * baseline;
    let orb = Orb::new(OrbConfig {
        n_features: 2000,
        ..OrbConfig::default()
    })?;
    let mut samples = Vec::new();
    let mut previous: Option<(usize, StereoFrame)> = None;
    let frames: Vec<usize> = (0..data.len()).step_by(gap).collect();
    for &j in &frames {
        let current = stereo_frame(&orb, &data, j)?;
        if let Some((i, before)) = &previous {
            let (Some(w_i), Some(w_j)) = (data.ground_truth_at(*i), data.ground_truth_at(j)) else {
                continue;
            };
            let t_ji = w_j.inverse() * w_i;
            let step = t_ji.translation.vector.norm();
            if step < 0.05 {
                continue;
            }
            for (a, knn) in knn2(
                before.features.descriptors(),
                current.features.descriptors(),
            )
            .iter()
            .enumerate()
            {
                if knn.best == u32::MAX
                    || f64::from(knn.best_distance) >= 0.8 * f64::from(knn.second_distance)
                {
                    continue;
                }
                let b = knn.best as usize;
                let (Some(mi), Some(mj)) = (&before.by_left[a], &current.by_left[b]) else {
                    continue;
                };
                let z_i = mi.depth(fb);
                let (u, v) = (
                    f64::from(before.features.xs()[a]),
                    f64::from(before.features.ys()[a]),
                );
                let p_i =
                    nalgebra::Point3::new((u - k.cx) / k.fx * z_i, (v - k.cy) / k.fy * z_i, z_i);
                let p_j = t_ji * p_i;
                if p_j.z <= 0.0 {
                    continue;
                }
                let (pu, pv) = (k.fx * p_j.x / p_j.z + k.cx, k.fy * p_j.y / p_j.z + k.cy);
                let (mu, mv) = (
                    f64::from(current.features.xs()[b]),
                    f64::from(current.features.ys()[b]),
                );
                if (pu - mu).hypot(pv - mv) > 3.0 {
                    continue;
                }
                let d_pred = fb / p_j.z;
                let s_i = KEYPOINT_QUANTISATION_PX * f64::from(mi.noise_scale);
                let s_j = KEYPOINT_QUANTISATION_PX * f64::from(mj.noise_scale);
                let gain = (d_pred / f64::from(mi.disparity)).powi(2);
                let residual = f64::from(mj.disparity) - d_pred;
                samples.push(Sample {
                    disparity: mj.disparity,
                    residual,
                    normalised: residual / (s_j * s_j + gain * gain * s_i * s_i).sqrt(),
                    step_excess: residual * fb / (d_pred * d_pred) / step,
                });
            }
        }
        previous = Some((j, current));
    }
    println!(
        "{} (gap {gap}): {} temporal matches",
        root.display(),
        samples.len()
    );
    println!(
        "  disparity px | count | median r px | spread r px | median r/sigma | spread r/sigma | beyond 3 sigma | step excess"
    );
    for (lo, hi) in BINS {
        let inside: Vec<&Sample> = samples
            .iter()
            .filter(|s| s.disparity >= lo && s.disparity < hi)
            .collect();
        if inside.len() < 10 {
            continue;
        }
        let r: Vec<f64> = inside.iter().map(|s| s.residual).collect();
        let n: Vec<f64> = inside.iter().map(|s| s.normalised).collect();
        let excess: Vec<f64> = inside.iter().map(|s| s.step_excess).collect();
        let beyond = n.iter().filter(|v| v.abs() > 3.0).count() as f64 / n.len() as f64;
        let (median_r, median_n) = (median(&r), median(&n));
        println!(
            "  {lo:>5.0}-{hi:<6.0} | {:>5} | {median_r:>11.3} | {:>11.3} | {median_n:>14.2} | {:>14.2} | {:>13.1}% | {:>10.1}%",
            inside.len(),
            mad_sigma(&r).unwrap_or(f64::NAN),
            mad_sigma(&n).unwrap_or(f64::NAN),
            100.0 * beyond,
            100.0 * median(&excess)
        );
    }
    Ok(())
}

fn main() {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let mut gap = 1;
    if let Some(k) = args.iter().position(|a| a == "--gap") {
        let Some(n) = args
            .get(k + 1)
            .and_then(|v| v.parse::<usize>().ok())
            .filter(|n| *n > 0)
        else {
            eprintln!("stereo_noise: --gap needs a positive count");
            std::process::exit(2);
        };
        gap = n;
        args.drain(k..k + 2);
    }
    let roots: Vec<PathBuf> = if args.is_empty() {
        ["kitti_06", "kitti_01"]
            .iter()
            .map(|c| PathBuf::from("../shared/data").join(c))
            .collect()
    } else {
        args.into_iter().map(PathBuf::from).collect()
    };
    for root in roots {
        if !root.exists() {
            eprintln!("stereo_noise: {} is absent, skipped", root.display());
            continue;
        }
        if let Err(e) = measure(&root, gap) {
            eprintln!("stereo_noise: {}: {e}", root.display());
        }
    }
}
