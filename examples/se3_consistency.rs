//! Does the direct SE(3) covariance describe its real errors, checked without a ground truth?
//!
//! On real clips the ground truth is itself noisy: KITTI's GPS/INS relative rotation between
//! consecutive frames scatters by a few hundredths of a degree (`tools/three_cornered_hat.py`),
//! ten times the direct alignment's sigma. So this example checks the covariance against
//! errors that it must explain by itself, on a rectified stereo clip (KITTI: `image_0` +
//! `image_1`), with the keyframes of `direct-stereo` (`vofront::odometry::direct_stereo`:
//! [`stereo_points`], the tracker's [`DirectStereoConfig`]):
//!
//! 1. **Split halves.** The reference of frame `i` is split into the two colours of a
//!    checkerboard of 64-pixel cells ([`Se3Reference::halves`], the check `direct-stereo`
//!    makes on a frame without a velocity); frame `i + 1` is aligned to each half. The two
//!    estimates see disjoint pixels, so their difference `d = log(T_A T_B^-1)` has the
//!    covariance `Sigma_A + Sigma_B` when the pixels' errors are independent beyond a cell.
//! 2. **Triangle loops.** `T_10` and `T_20` (frames `i + 1`, `i + 2` aligned to keyframe `i`)
//!    and `T_21` (frame `i + 2` aligned to keyframe `i + 1`, its own stereo depths). With left
//!    increments `T = exp(e) T_true`, the loop `d = log(T_20 (T_21 T_10)^-1)` is
//!    `e_20 - e_21 - Ad(T_21) e_10` to first order, of covariance
//!    `Sigma_20 + Sigma_21 + Ad(T_21) Sigma_10 Ad(T_21)^T`.
//!
//! For each check and block (rotation, translation) it prints the median and mean NEES per
//! degree of freedom (`d^T B^-1 d / 3`, near 1 when the covariance is right), the median of
//! `|d| / sqrt(trace B)` (the error/sigma of `quality_real`) and the share beyond 5 sigma.
//! Neither check sees an error common to every alignment of a frame (the same in both halves,
//! cancelling around a loop), such as a calibration error, so the alignments run without the
//! covariance's calibration share (`Se3Config::calibration` exact): what is checked is the
//! photometric sandwich covariance.
//!
//! `cargo run --release --example se3_consistency [-- DATASET ...]` (default: the shared
//! `kitti_06` and `kitti_01`; a folder that is absent is skipped with a message).

use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Matrix3, Matrix6, Vector3, Vector6};
use vofront::core::camera::Lens;
use vofront::core::lie::{adjoint, se3_log};
use vofront::dataset::Dataset;
use vofront::direct::{CalibrationPrior, InverseDepthPoint, Se3Reference, Se3Result};
use vofront::image::Image;
use vofront::odometry::direct_stereo::{stereo_points, DirectStereoConfig};

/// NEES per degree of freedom and error/sigma of the 3-vector `d` under the 3x3 block `b`.
fn normalised(d: Vector3<f64>, b: Matrix3<f64>) -> Option<(f64, f64)> {
    let nees = d.dot(&(b.try_inverse()? * d)) / 3.0;
    Some((nees, d.norm() / b.trace().sqrt()))
}

/// The samples of one check: `(NEES/dof, error/sigma)` of rotation and of translation.
#[derive(Default)]
struct Check {
    rotation: Vec<(f64, f64)>,
    translation: Vec<(f64, f64)>,
    /// Frames whose rotation or translation lies beyond 5 sigma.
    beyond: Vec<usize>,
}

impl Check {
    /// Adds the discrepancy `d = (rho, phi)` of covariance `cov` found at frame `frame`.
    fn add(&mut self, frame: usize, d: &Vector6<f64>, cov: &Matrix6<f64>) {
        let block = |s: usize| -> (Vector3<f64>, Matrix3<f64>) {
            (
                d.fixed_rows::<3>(s).into_owned(),
                cov.fixed_view::<3, 3>(s, s).into_owned(),
            )
        };
        let (t, bt) = block(0);
        let (r, br) = block(3);
        let (t, r) = (normalised(t, bt), normalised(r, br));
        if t.iter().chain(&r).any(|s| s.1 > 5.0) {
            self.beyond.push(frame);
        }
        self.translation.extend(t);
        self.rotation.extend(r);
    }

    fn print(&self, name: &str) {
        for (block, samples) in [
            ("rotation", &self.rotation),
            ("translation", &self.translation),
        ] {
            let mut nees: Vec<f64> = samples.iter().map(|s| s.0).collect();
            let mut ratio: Vec<f64> = samples.iter().map(|s| s.1).collect();
            let n = samples.len().max(1) as f64;
            let mean = nees.iter().sum::<f64>() / n;
            let beyond = ratio.iter().filter(|r| **r > 5.0).count() as f64 / n;
            println!(
                "  {name:<12} {block:<12} n {:3}  NEES/dof median {:5.2} mean {:6.2}  error/sigma median {:5.2}  beyond 5 sigma {:5.1}%",
                samples.len(),
                median(&mut nees),
                mean,
                median(&mut ratio),
                100.0 * beyond
            );
        }
        if !self.beyond.is_empty() {
            println!("  {name:<12} frames beyond 5 sigma: {:?}", self.beyond);
        }
    }
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

/// The `T_cur_ref` of `current` aligned to `reference` from `prior`, with its covariance;
/// `None` (counted as a failure) when the alignment fails or has no covariance.
fn align(
    reference: &Se3Reference,
    current: &Image<f32>,
    prior: &Isometry3<f64>,
    cfg: &DirectStereoConfig,
) -> Option<(Se3Result, Matrix6<f64>)> {
    let fit = reference.align(current, prior, &cfg.se3).ok()?;
    let cov = fit.covariance?;
    Some((fit, cov))
}

/// The left and right images of frame `i`, as `f32`.
fn stereo_images(data: &Dataset, i: usize) -> Option<(Image<f32>, Image<f32>)> {
    let frame = data.load_stereo(i).ok()?;
    Some((frame.image().to_f32(), frame.right()?.to_f32()))
}

fn run(path: &Path) -> Result<(), String> {
    let data = Dataset::open(path).map_err(|e| e.to_string())?;
    let rig = data.rig.as_ref().ok_or("no calibration")?;
    let t_rl = rig.t_right_left().ok_or("no right camera")?;
    let left = rig.left();
    // A rectified rig (KITTI) only: no distortion, no rotation between the cameras.
    if left.distortion != Lens::default() || t_rl.rotation.angle() > 1e-9 {
        return Err("needs a rectified stereo rig (a KITTI folder)".into());
    }
    let (pinhole, fb) = (left.pinhole, left.pinhole.fx * t_rl.translation.x.abs());
    let mut cfg = DirectStereoConfig::default();
    cfg.se3.calibration = CalibrationPrior::exact();
    let reference = |points: &[InverseDepthPoint], image: &Image<f32>| {
        Se3Reference::from_inverse_depths(image, pinhole, None, points, &cfg.se3).ok()
    };
    let (mut halves, mut loops, mut failed) = (Check::default(), Check::default(), 0usize);
    let mut motion = Isometry3::identity();
    for i in 0..data.len().saturating_sub(2) {
        let images = |k: usize| stereo_images(&data, k);
        let points = |(l, r): &(Image<f32>, Image<f32>)| stereo_points(l, r, fb, &cfg).ok();
        let fits = (|| {
            let (first, second, (l2, _)) = (images(i)?, images(i + 1)?, images(i + 2)?);
            let (l0, l1) = (&first.0, &second.0);
            let k0 = reference(&points(&first)?, l0)?;
            let (f10, c10) = align(&k0, l1, &motion, &cfg)?;
            let (f20, c20) = align(&k0, &l2, &(f10.pose * f10.pose), &cfg)?;
            let (f21, c21) = align(&reference(&points(&second)?, l1)?, &l2, &f10.pose, &cfg)?;
            let [a, b] = k0.halves();
            let (fa, ca) = align(&a, l1, &f10.pose, &cfg)?;
            let (fb, cb) = align(&b, l1, &f10.pose, &cfg)?;
            Some([(f10, c10), (f20, c20), (f21, c21), (fa, ca), (fb, cb)])
        })();
        let Some([(f10, c10), (f20, c20), (f21, c21), (fa, ca), (fb, cb)]) = fits else {
            failed += 1;
            continue;
        };
        motion = f10.pose;
        halves.add(i, &se3_log(&(fa.pose * fb.pose.inverse())), &(ca + cb));
        let ad = adjoint(&f21.pose);
        loops.add(
            i,
            &se3_log(&(f20.pose * (f21.pose * f10.pose).inverse())),
            &(c20 + c21 + ad * c10 * ad.transpose()),
        );
    }
    println!(
        "{} ({} frames, {failed} triples without a result)",
        path.display(),
        data.len()
    );
    halves.print("split halves");
    loops.print("loops");
    Ok(())
}

fn main() {
    let args: Vec<PathBuf> = std::env::args().skip(1).map(PathBuf::from).collect();
    let paths = if args.is_empty() {
        ["kitti_06", "kitti_01"]
            .iter()
            .map(|c| Path::new("../shared/data").join(c))
            .collect()
    } else {
        args
    };
    for path in paths {
        if !path.exists() {
            println!("{}: absent, skipped", path.display());
            continue;
        }
        if let Err(e) = run(&path) {
            println!("{}: {e}", path.display());
        }
    }
}
