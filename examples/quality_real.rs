//! Predicted sigma against actual error on the shared real pairs: the TUM fr1 pairs with motion
//! capture (feature and direct SE(3) poses; `case_1` also backwards, its current depth being
//! trustworthy) and every consecutive and 3-apart pair of the KITTI clips with `poses.txt`
//! (feature poses). Skips what is absent.
//!
//! `cargo run --release --example quality_real -- [DATA_DIR] [KITTI_STEPS] [--quiet]` (default
//! `../shared/data`, steps `1,3`: pairs `(k, k + step)` for every `k`).
//!
//! Per pair it prints the verdict, the errors against the ground truth and the predicted
//! sigmas; then, per estimator, the distribution of error / sigma (median, 90th percentile,
//! share beyond 5 sigma) and the verdict counts among the pairs within 2 deg of rotation and
//! 20 deg of translation direction ("good") and outside them. Error / sigma compares an angle
//! with the RMS of its covariance (`sqrt(trace)`): 1 on average when the covariance is right.

use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Matrix3, Quaternion, Translation3, UnitQuaternion};
use vofront::geometry::lie::direction_angle_deg;
use vofront::input::{load_depth, load_gray};
use vofront::pipeline::FeaturePose;
use vofront::presets::camera_preset;
use vofront::robust::{Quality, Verdict};
use vofront::two_view::{estimate, Inputs, Method};

/// Largest rotation error of a good pose, degrees.
const GOOD_ROTATION_DEG: f64 = 2.0;
/// Largest translation-direction error of a good pose, degrees.
const GOOD_DIRECTION_DEG: f64 = 20.0;

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

/// Error / sigma samples and verdict counts of one estimator.
#[derive(Default)]
struct Tally {
    /// Rotation error / rotation sigma per estimate.
    rotation: Vec<f64>,
    /// Translation error (direction, degrees; or metric) / its sigma per estimate.
    translation: Vec<f64>,
    /// `[ok, unreliable, failed]` among the good pairs.
    good: [usize; 3],
    /// `[ok, unreliable, failed]` among the other pairs.
    bad: [usize; 3],
    /// The reasons of the good pairs that are not ok, with counts.
    good_reasons: Vec<(String, usize)>,
}

impl Tally {
    fn add(&mut self, q: &Quality, errors: Errors, trans: (f64, Option<f64>)) {
        if let Some(s) = q.uncertainty.rotation_sigma_deg.filter(|s| *s > 0.0) {
            self.rotation.push(errors.rotation_deg / s);
        }
        if let Some(s) = trans.1.filter(|s| *s > 0.0 && trans.0.is_finite()) {
            self.translation.push(trans.0 / s);
        }
        let slot = match q.verdict {
            Verdict::Ok => 0,
            Verdict::Unreliable => 1,
            Verdict::Failed => 2,
        };
        if errors.rotation_deg <= GOOD_ROTATION_DEG && errors.direction_deg <= GOOD_DIRECTION_DEG {
            self.good[slot] += 1;
            if slot > 0 {
                let key = q
                    .reasons
                    .iter()
                    .map(|r| r.name())
                    .collect::<Vec<_>>()
                    .join(",");
                match self.good_reasons.iter_mut().find(|(k, _)| *k == key) {
                    Some((_, n)) => *n += 1,
                    None => self.good_reasons.push((key, 1)),
                }
            }
        } else {
            self.bad[slot] += 1;
        }
    }

    fn print(&self, name: &str, rotation: &str, translation: &str) {
        println!(
            "{name} {rotation:<22} error/sigma: {}",
            summary(&self.rotation)
        );
        println!(
            "{name} {translation:<22} error/sigma: {}",
            summary(&self.translation)
        );
        println!(
            "{name} verdicts: good pairs ok {} / unreliable {} / failed {}; other pairs ok {} / unreliable {} / failed {}",
            self.good[0], self.good[1], self.good[2], self.bad[0], self.bad[1], self.bad[2]
        );
        for (reasons, n) in &self.good_reasons {
            println!("{name}   good but not ok: {n:3} x [{reasons}]");
        }
    }
}

/// `median, 90th percentile, share beyond 5` of error / sigma samples.
fn summary(v: &[f64]) -> String {
    if v.is_empty() {
        return "no samples".into();
    }
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let at = |p: f64| s[((s.len() - 1) as f64 * p).round() as usize];
    let beyond = s.iter().filter(|&&x| x > 5.0).count();
    format!(
        "n {:3}  median {:6.2}  p90 {:7.2}  beyond 5 sigma {:5.1}%",
        s.len(),
        at(0.5),
        at(0.9),
        100.0 * beyond as f64 / s.len() as f64
    )
}

/// Errors of an estimate against the truth.
#[derive(Clone, Copy)]
struct Errors {
    rotation_deg: f64,
    /// Angle between the translations (NaN for a zero estimate), degrees.
    direction_deg: f64,
    /// `|t - t_true|`, metres.
    metric_m: f64,
}

impl Errors {
    fn new(pose: &Isometry3<f64>, truth: &Isometry3<f64>) -> Self {
        let (t, tt) = (pose.translation.vector, truth.translation.vector);
        Self {
            rotation_deg: pose.rotation.angle_to(&truth.rotation).to_degrees(),
            direction_deg: if t.norm() > 0.0 {
                direction_angle_deg(&t, &tt)
            } else {
                f64::NAN
            },
            metric_m: (t - tt).norm(),
        }
    }
}

#[derive(Default)]
struct Harness {
    quiet: bool,
    feature: Tally,
    se3: Tally,
}

impl Harness {
    fn feature(&mut self, name: &str, f: &FeaturePose, truth: &Isometry3<f64>) {
        let (q, e) = (&f.estimate.quality, Errors::new(&f.estimate.pose, truth));
        let u = &q.uncertainty;
        if !self.quiet {
            println!(
                "{name:<18} feature    {:<10} rot err {:7.3} deg (sigma {:7.3})  dir err {:7.2} deg (sigma {:7.2})  parallax {:5.2} deg  inliers {:4} of {:4} [{}]",
                q.verdict.to_string(),
                e.rotation_deg,
                u.rotation_sigma_deg.unwrap_or(f64::NAN),
                e.direction_deg,
                u.translation_direction_sigma_deg.unwrap_or(f64::NAN),
                f.estimate.parallax_deg,
                q.support.inliers,
                q.support.candidates,
                reasons(q),
            );
        }
        self.feature
            .add(q, e, (e.direction_deg, u.translation_direction_sigma_deg));
    }

    fn se3(&mut self, name: &str, q: &Quality, pose: &Isometry3<f64>, truth: &Isometry3<f64>) {
        let e = Errors::new(pose, truth);
        let u = &q.uncertainty;
        if !self.quiet {
            println!(
                "{name:<18} direct_se3 {:<10} rot err {:7.3} deg (sigma {:7.3})  t err {:6.1} mm (sigma {:6.1})  dir err {:7.2} deg [{}]",
                q.verdict.to_string(),
                e.rotation_deg,
                u.rotation_sigma_deg.unwrap_or(f64::NAN),
                e.metric_m * 1e3,
                u.translation_sigma_m.unwrap_or(f64::NAN) * 1e3,
                e.direction_deg,
                reasons(q),
            );
        }
        self.se3.add(q, e, (e.metric_m, u.translation_sigma_m));
    }
}

fn reasons(q: &Quality) -> String {
    q.reasons
        .iter()
        .map(|r| r.name())
        .collect::<Vec<_>>()
        .join(",")
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let quiet = args.iter().any(|a| a == "--quiet");
    let positional: Vec<&String> = args.iter().filter(|a| !a.starts_with("--")).collect();
    let data = PathBuf::from(positional.first().map_or("../shared/data", |s| s.as_str()));
    let steps: Vec<usize> = positional.get(1).map_or(vec![1, 3], |s| {
        s.split(',').filter_map(|v| v.parse().ok()).collect()
    });
    let mut h = Harness {
        quiet,
        ..Harness::default()
    };
    let tum = data.join("tum_fr1_xyz_pairs");
    // (case, reversed): case_2's current depth is case_1's (see the data README), so only
    // case_1 runs backwards.
    for (case, reversed) in [("case_1", false), ("case_2", false), ("case_1", true)] {
        let dir = tum.join(case);
        let (first, second) = if reversed {
            ("curr", "prev")
        } else {
            ("prev", "curr")
        };
        let (Some(p1), Some(p2)) = (
            tum_pose(&dir.join(format!("pose_{first}.txt"))),
            tum_pose(&dir.join(format!("pose_{second}.txt"))),
        ) else {
            println!("{}: absent, skipped", dir.display());
            continue;
        };
        let (Ok(img1), Ok(img2)) = (
            load_gray(&dir.join(format!("img_{first}.png"))),
            load_gray(&dir.join(format!("img_{second}.png"))),
        ) else {
            println!("{}: unreadable, skipped", dir.display());
            continue;
        };
        let Some(camera) = camera_preset("tum-fr1").map(|p| p.camera) else {
            return;
        };
        let o = estimate(&Inputs {
            img1,
            img2,
            depth1: load_depth(&dir.join(format!("dep_{first}.png")), 5000.0).ok(),
            camera,
            method: Method::All,
            features: 2000,
            stereo: None,
        });
        let truth = p2.inverse() * p1;
        let name = format!("tum {case}{}", if reversed { " back" } else { "" });
        if let Some(Ok(f)) = &o.feature {
            h.feature(&name, f, &truth);
        }
        if let Some(Ok((s, _))) = &o.se3 {
            h.se3(&name, &s.quality, &s.pose, &truth);
        }
    }
    for (clip, preset) in [("kitti_06", "kitti-04-12"), ("kitti_01", "kitti-00-02")] {
        let dir = data.join(clip);
        let poses = kitti_poses(&dir.join("poses.txt"));
        let Some(camera) = camera_preset(preset).map(|p| p.camera) else {
            return;
        };
        if poses.is_empty() {
            println!("{}: absent, skipped", dir.display());
            continue;
        }
        for &step in &steps {
            for k in 0..poses.len().saturating_sub(step) {
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
                    stereo: None,
                });
                let name = format!("{clip} {k}-{}", k + step);
                match &o.feature {
                    Some(Ok(f)) => h.feature(&name, f, &truth),
                    Some(Err(e)) => println!("{name:<18} feature    error: {e}"),
                    None => {}
                }
            }
        }
    }
    println!(
        "-- within {GOOD_ROTATION_DEG} deg rotation and {GOOD_DIRECTION_DEG} deg direction: good"
    );
    h.feature.print("feature   ", "rotation", "direction");
    h.se3
        .print("direct_se3", "rotation", "translation (metric)");
}
