//! Predicted sigma against actual error on the shared real pairs (TUM fr1 pairs with motion
//! capture, KITTI clips with poses.txt). Skips what is absent.
//!
//! `cargo run --release --example quality_real -- [DATA_DIR] [KITTI_STEP]` (default
//! `../shared/data`, step 5: pairs (k, k + step) for k = 0, step, ...).

use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Matrix3, Quaternion, Translation3, UnitQuaternion};
use vofront::geometry::lie::direction_angle_deg;
use vofront::input::{load_depth, load_gray};
use vofront::presets::camera_preset;
use vofront::robust::Quality;
use vofront::two_view::{estimate, Inputs, Method};

fn tum_pose(path: &Path) -> Option<Isometry3<f64>> {
    let text = std::fs::read_to_string(path).ok()?;
    let v: Vec<f64> = text
        .split_whitespace()
        .filter_map(|s| s.parse().ok())
        .collect();
    let q = UnitQuaternion::from_quaternion(Quaternion::new(v[6], v[3], v[4], v[5]));
    Some(Isometry3::from_parts(
        Translation3::new(v[0], v[1], v[2]),
        q,
    ))
}

fn kitti_poses(path: &Path) -> Vec<Isometry3<f64>> {
    let text = std::fs::read_to_string(path).unwrap_or_default();
    text.lines()
        .filter_map(|l| {
            let v: Vec<f64> = l
                .split_whitespace()
                .filter_map(|s| s.parse().ok())
                .collect();
            (v.len() == 12).then(|| {
                let r = Matrix3::new(v[0], v[1], v[2], v[4], v[5], v[6], v[8], v[9], v[10]);
                let rot = UnitQuaternion::from_matrix(&r);
                Isometry3::from_parts(Translation3::new(v[3], v[7], v[11]), rot)
            })
        })
        .collect()
}

fn line(name: &str, what: &str, q: &Quality, pose: &Isometry3<f64>, truth: &Isometry3<f64>) {
    let rot = pose.rotation.angle_to(&truth.rotation).to_degrees();
    let t = pose.translation.vector;
    let tt = truth.translation.vector;
    let u = &q.uncertainty;
    let dir = if t.norm() > 0.0 {
        direction_angle_deg(&t, &tt)
    } else {
        f64::NAN
    };
    let metric = (t - tt).norm();
    println!(
        "{name:<16} {what:<10} {:<10} rot err {rot:7.3} deg (sigma {:7.3})  dir err {dir:7.2} deg (sigma {:7.2})  t err {:6.1} mm (sigma {:6.1})  [{}]",
        q.verdict.to_string(),
        u.rotation_sigma_deg.unwrap_or(f64::NAN),
        u.translation_direction_sigma_deg.unwrap_or(f64::NAN),
        metric * 1e3,
        u.translation_sigma_m.unwrap_or(f64::NAN) * 1e3,
        q.reasons.iter().map(|r| r.name()).collect::<Vec<_>>().join(","),
    );
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let data = PathBuf::from(args.get(1).map_or("../shared/data", String::as_str));
    let step: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(5);
    for case in ["case_1", "case_2"] {
        let dir = data.join("tum_fr1_xyz_pairs").join(case);
        let (Some(p1), Some(p2)) = (
            tum_pose(&dir.join("pose_prev.txt")),
            tum_pose(&dir.join("pose_curr.txt")),
        ) else {
            println!("{}: absent, skipped", dir.display());
            continue;
        };
        let truth = p2.inverse() * p1;
        let inputs = Inputs {
            img1: load_gray(&dir.join("img_prev.png")).expect("image"),
            img2: load_gray(&dir.join("img_curr.png")).expect("image"),
            depth1: load_depth(&dir.join("dep_prev.png"), 5000.0).ok(),
            camera: camera_preset("tum-fr1").expect("preset").camera,
            method: Method::All,
            features: 2000,
        };
        let o = estimate(&inputs);
        if let Some(Ok(f)) = &o.feature {
            line(
                case,
                "feature",
                &f.estimate.quality,
                &f.estimate.pose,
                &truth,
            );
        }
        if let Some(Ok((s, _))) = &o.se3 {
            line(case, "direct_se3", &s.quality, &s.pose, &truth);
        }
    }
    for (clip, preset) in [("kitti_06", "kitti-04-12"), ("kitti_01", "kitti-00-02")] {
        let dir = data.join(clip);
        let poses = kitti_poses(&dir.join("poses.txt"));
        if poses.is_empty() {
            println!("{}: absent, skipped", dir.display());
            continue;
        }
        let camera = camera_preset(preset).expect("preset").camera;
        let mut k = 0;
        while k + step < poses.len() {
            let img = |i: usize| load_gray(&dir.join("image_0").join(format!("{i:06}.png")));
            let (Ok(img1), Ok(img2)) = (img(k), img(k + step)) else {
                break;
            };
            let truth = poses[k + step].inverse() * poses[k];
            let o = estimate(&Inputs {
                img1,
                img2,
                depth1: None,
                camera,
                method: Method::Feature,
                features: 2000,
            });
            let name = format!("{clip} {k}-{}", k + step);
            match &o.feature {
                Some(Ok(f)) => line(
                    &name,
                    "feature",
                    &f.estimate.quality,
                    &f.estimate.pose,
                    &truth,
                ),
                Some(Err(e)) => println!("{name:<16} feature    error: {e}"),
                None => {}
            }
            k += step;
        }
    }
}
