//! The rotation scale of the relative pose error: the least-squares factor between estimated
//! and true relative rotations, the scale-free sign of a focal length that disagrees with the
//! ground truth (a tracker with the focal too long by `k` turns by about `1 / k` of the truth).

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use vofront::eval::{rpe, Alignment, EvalConfig};
use vofront::fixtures::scene::room_trajectory;
use vofront::trajectory::Trajectory;

/// Exact inputs leave only rounding.
const EXACT_TOLERANCE: f64 = 1e-9;

/// Camera-to-world poses of a car-like drive: 1 m forward per frame along the camera's `z`
/// while turning about its `y` axis by `yaw_deg` per frame (and a slight, varying pitch), at
/// 10 Hz.
fn turning_drive(frames: usize, yaw_deg: f64) -> Trajectory {
    let mut pose = Isometry3::identity();
    let mut poses = Vec::with_capacity(frames);
    for i in 0..frames {
        poses.push((i as f64 / 10.0, pose));
        let pitch = 0.2_f64.to_radians() * (0.3 * i as f64).sin();
        let step = Isometry3::from_parts(
            Translation3::new(0.0, 0.0, 1.0),
            UnitQuaternion::from_euler_angles(pitch, yaw_deg.to_radians(), 0.0),
        );
        pose *= step;
    }
    Trajectory::new(poses)
}

/// `gt` with every relative rotation `R_k = exp(w_k)` replaced by `exp(scale w_k + noise_k)`
/// (translations of the steps kept), composed from the first pose.
fn rescaled(gt: &Trajectory, scale: f64, noise: impl Fn(usize) -> Vector3<f64>) -> Trajectory {
    let mut pose = gt.poses[0].1;
    let mut poses = vec![(gt.poses[0].0, pose)];
    for (k, w) in gt.poses.windows(2).enumerate() {
        let step = w[0].1.inverse() * w[1].1;
        let axis = step.rotation.scaled_axis() * scale + noise(k);
        pose *= Isometry3::from_parts(step.translation, UnitQuaternion::from_scaled_axis(axis));
        poses.push((w[1].0, pose));
    }
    Trajectory::new(poses)
}

fn config(alignment: Alignment) -> EvalConfig {
    EvalConfig {
        alignment,
        ..EvalConfig::default()
    }
}

#[test]
fn a_uniform_shrink_of_every_rotation_is_recovered_exactly() {
    for gt in [turning_drive(40, 2.0), {
        let poses = room_trajectory(90).into_iter().enumerate();
        Trajectory::new(poses.map(|(i, p)| (i as f64 / 30.0, p)).collect())
    }] {
        for scale in [0.97, 0.99, 1.0, 1.02] {
            let est = rescaled(&gt, scale, |_| Vector3::zeros());
            for alignment in [Alignment::None, Alignment::Sim3] {
                let fit = rpe(&gt, &est, &config(alignment))
                    .expect("rpe")
                    .rotation_scale
                    .expect("the trajectory rotates");
                assert!(
                    (fit.scale - scale).abs() < EXACT_TOLERANCE,
                    "{fit:?} vs {scale}"
                );
                assert!(fit.sigma < EXACT_TOLERANCE, "{fit:?}");
            }
        }
    }
}

/// Deterministic, uncorrelated-looking noise with standard deviation `sigma_rad` per component.
fn noise(sigma_rad: f64) -> impl Fn(usize) -> Vector3<f64> {
    move |k: usize| {
        let x = k as f64 + 1.0;
        let u = |a: f64| ((a * x).sin() * 43_758.545).rem_euclid(1.0) * 2.0 - 1.0;
        Vector3::new(u(12.9898), u(78.233), u(37.719)) * sigma_rad * 3.0_f64.sqrt()
    }
}

#[test]
fn zero_mean_noise_leaves_the_scale_within_its_sigma() {
    let (frames, yaw_deg) = (60, 2.0);
    let gt = turning_drive(frames, yaw_deg);
    for noise_deg in [0.02, 0.05, 0.1] {
        let noise_rad = f64::to_radians(noise_deg);
        // Per-component noise over the root of the summed squared true angles.
        let pairs = (frames - 1) as f64;
        let expected_sigma = noise_rad / (pairs.sqrt() * yaw_deg.to_radians());
        for scale in [0.99, 1.0] {
            let est = rescaled(&gt, scale, noise(noise_rad));
            let fit = rpe(&gt, &est, &config(Alignment::Sim3))
                .expect("rpe")
                .rotation_scale
                .expect("the trajectory rotates");
            assert!(
                fit.sigma > 0.5 * expected_sigma && fit.sigma < 2.0 * expected_sigma,
                "{fit:?}, expected sigma {expected_sigma:.5}"
            );
            assert!(
                (fit.scale - scale).abs() < 4.0 * fit.sigma,
                "{fit:?} vs {scale}"
            );
        }
    }
    // At 0.02 deg of noise per frame a 1% shrink stands several sigma clear of 1.
    let est = rescaled(&gt, 0.99, noise(0.02_f64.to_radians()));
    let shrunk = rpe(&gt, &est, &config(Alignment::Sim3)).expect("rpe");
    let fit = shrunk.rotation_scale.expect("the trajectory rotates");
    assert!(1.0 - fit.scale > 4.0 * fit.sigma, "{fit:?}");
}

#[test]
fn a_trajectory_without_rotation_has_no_rotation_scale() {
    let gt = turning_drive(20, 0.0);
    let poses = gt.poses.iter().map(|(t, p)| {
        let mut flat = *p;
        flat.rotation = UnitQuaternion::identity();
        (*t, flat)
    });
    let straight = Trajectory::new(poses.collect());
    let r = rpe(&straight, &straight, &config(Alignment::None)).expect("rpe");
    assert_eq!(r.rotation_scale, None);
    let turning = turning_drive(20, 1.0);
    let r = rpe(&turning, &turning, &config(Alignment::None)).expect("rpe");
    let fit = r.rotation_scale.expect("the trajectory rotates");
    assert!((fit.scale - 1.0).abs() < EXACT_TOLERANCE, "{fit:?}");
}

#[test]
fn eval_command_reports_the_rotation_scale_in_text_and_json() {
    let dir = std::env::temp_dir().join(format!("vofront-rotation-scale-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let gt = turning_drive(30, 3.0);
    gt.write_tum(&dir.join("gt.txt")).expect("write gt");
    rescaled(&gt, 0.98, |_| Vector3::zeros())
        .write_tum(&dir.join("est.txt"))
        .expect("write est");
    let run = |extra: &[&str]| {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_vofront"))
            .args(["eval", "gt.txt", "est.txt", "--align", "sim3"])
            .args(extra)
            .current_dir(&dir)
            .output()
            .expect("run vofront");
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8(out.stdout).expect("utf-8")
    };
    let text = run(&[]);
    let line = text
        .lines()
        .find(|l| l.starts_with("RPE rot scale"))
        .unwrap_or_else(|| panic!("no rotation scale line in\n{text}"));
    assert!(line.contains("0.98"), "{line}");
    let json: serde_json::Value = serde_json::from_str(&run(&["--json"])).expect("one object");
    let scale = json["rpe"]["rotation_scale"]["scale"]
        .as_f64()
        .expect("scale");
    // The TUM file keeps 9 decimals of each quaternion.
    assert!((scale - 0.98).abs() < 1e-6, "{json}");
    assert!(
        json["rpe"]["rotation_scale"]["sigma"]
            .as_f64()
            .expect("sigma")
            < 1e-6
    );
    std::fs::remove_dir_all(&dir).expect("clean up");
}
