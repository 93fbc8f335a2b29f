//! SE(3) direct alignment on a TUM RGB-D pair against ground truth, timed like
//! `opencv_peer.py rgbd` (frame preparation included).
//!
//! Usage:
//! `cargo run --release -p vofront-direct --example rgbd_tum -- CASE_DIR [REPS] [LOSS] [K]`
//! where `CASE_DIR` holds `img_prev.png`, `dep_prev.png`, `img_curr.png`, `dep_curr.png`
//! (depth in 1/5000 m) and `pose_prev.txt`, `pose_curr.txt` (`tx ty tz qx qy qz qw`,
//! camera-to-world), and `LOSS` is `huber` (default) or `student`. The camera is TUM
//! freiburg1 (517.3, 516.5, 318.6, 255.3, distortion 0.2624 -0.9531 -0.0054 0.0026 1.1633)
//! unless `K` = `fx,fy,cx,cy` gives a pinhole camera without distortion (e.g. `525,525,319.5,239.5`
//! for the pairs written by `vofront-fixtures`' `render_pairs` example).
//! The undistortion map is built once outside the timed loop (it depends on the camera only).
//! Prints the estimate of `T_21 = T_w_curr^-1 T_w_prev` (the reference is the previous frame),
//! its rotation and translation errors, and the median time.

use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};
use vofront_core::{Camera, Distortion, Pinhole};
use vofront_direct::{align_se3, RgbdFrame, Se3Config, Undistorter};
use vofront_image::Image;
use vofront_robust::Loss;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 2 {
        eprintln!("usage: rgbd_tum CASE_DIR [REPS] [huber|student] [fx,fy,cx,cy]");
        std::process::exit(2);
    }
    let dir = Path::new(&args[1]);
    if !dir.exists() {
        eprintln!("{} not found, skipping", dir.display());
        return Ok(());
    }
    let reps: usize = args.get(2).map_or(Ok(10), |s| s.parse())?;
    let loss = match args.get(3).map(String::as_str) {
        Some("student") => Loss::StudentT(5.0),
        _ => Loss::Huber(1.345),
    };
    let camera = match args.get(4) {
        Some(k) => {
            let k: Vec<f64> = k.split(',').map(str::parse).collect::<Result<_, _>>()?;
            if k.len() != 4 {
                return Err("K must be fx,fy,cx,cy".into());
            }
            Camera::pinhole(Pinhole::new(k[0], k[1], k[2], k[3])?)
        }
        None => Camera::new(
            Pinhole::new(517.3, 516.5, 318.6, 255.3)?,
            Distortion::from_array([0.2624, -0.9531, -0.0054, 0.0026, 1.1633]),
        ),
    };
    let grey = |name: &str| -> Result<Image<f32>, Box<dyn std::error::Error>> {
        Ok(Image::from_gray8(&image::open(dir.join(name))?.to_luma8()))
    };
    let depth = |name: &str| -> Result<Image<f32>, Box<dyn std::error::Error>> {
        let raw = image::open(dir.join(name))?.to_luma16();
        let data = raw
            .as_raw()
            .iter()
            .map(|&v| f32::from(v) / 5000.0)
            .collect();
        Ok(Image::new(
            raw.width() as usize,
            raw.height() as usize,
            data,
        )?)
    };
    let (img_prev, dep_prev, img_curr) = (
        grey("img_prev.png")?,
        depth("dep_prev.png")?,
        grey("img_curr.png")?,
    );
    let truth =
        read_pose(&dir.join("pose_curr.txt"))?.inverse() * read_pose(&dir.join("pose_prev.txt"))?;
    let cfg = Se3Config {
        loss,
        ..Se3Config::default()
    };
    // The undistortion map depends on the camera only: built once, like a calibration.
    let undistorter = if camera.distortion.is_identity() {
        None
    } else {
        Some(Arc::new(Undistorter::new(
            &camera,
            img_prev.width(),
            img_prev.height(),
        )?))
    };
    let mut times = Vec::new();
    let mut prepare_times = Vec::new();
    let mut fit = None;
    for _ in 0..reps.max(1) {
        let start = Instant::now();
        let reference = RgbdFrame::with_undistorter(
            img_prev.clone(),
            dep_prev.clone(),
            camera.pinhole,
            undistorter.clone(),
        )?;
        prepare_times.push(start.elapsed().as_secs_f64() * 1e3);
        fit = Some(align_se3(
            &reference,
            &img_curr,
            &Isometry3::identity(),
            &cfg,
        )?);
        times.push(start.elapsed().as_secs_f64() * 1e3);
    }
    times.sort_by(f64::total_cmp);
    prepare_times.sort_by(f64::total_cmp);
    let fit = fit.expect("at least one repetition");
    let rot_err = fit.pose.rotation.angle_to(&truth.rotation).to_degrees();
    let trans_err = (fit.pose.translation.vector - truth.translation.vector).norm();
    let t = fit.pose.translation.vector;
    println!(
        "{{\"t\": [{:.5}, {:.5}, {:.5}], \"truth_t\": [{:.5}, {:.5}, {:.5}], \"rot_err_deg\": {:.4}, \"trans_err_m\": {:.5}, \"truth_angle_deg\": {:.3}, \"ms\": {:.2}, \"prepare_ms\": {:.2}, \"iterations\": {:?}, \"valid\": {}, \"inliers\": {:.3}, \"a\": {:.3}, \"b\": {:.2}, \"reason\": \"{:?}\"}}",
        t.x, t.y, t.z,
        truth.translation.x, truth.translation.y, truth.translation.z,
        rot_err,
        trans_err,
        truth.rotation.angle().to_degrees(),
        times[times.len() / 2],
        prepare_times[prepare_times.len() / 2],
        fit.iterations,
        fit.valid_pixels,
        fit.inlier_ratio,
        fit.a,
        fit.b,
        fit.reason
    );
    Ok(())
}

/// A TUM pose line `tx ty tz qx qy qz qw` (camera-to-world).
fn read_pose(path: &Path) -> Result<Isometry3<f64>, Box<dyn std::error::Error>> {
    let text = std::fs::read_to_string(path)?;
    let v: Vec<f64> = text
        .split_whitespace()
        .map(str::parse)
        .collect::<Result<_, _>>()?;
    if v.len() < 7 {
        return Err(format!("{}: expected 7 numbers", path.display()).into());
    }
    Ok(Isometry3::from_parts(
        Translation3::new(v[0], v[1], v[2]),
        UnitQuaternion::from_quaternion(Quaternion::new(v[6], v[3], v[4], v[5])),
    ))
}
