//! `vofront two-view`: feature and direct estimates of one frame pair, as text or JSON, with
//! pictures. The demo reuses [`estimate`], [`print_text`] and [`write_pictures`].

use std::path::Path;
use std::time::Instant;

use image::GrayImage;
use nalgebra::{Isometry3, Matrix3};
use serde_json::{json, Value};
use vofront::direct::{
    align_se3, align_translation, photometric_residual_map, DirectError, RgbdFrame, Se3Config,
    Se3Result, TranslationConfig, TranslationResult,
};
use vofront::draw;
use vofront::geometry::{Camera, Model};
use vofront::input::{load_depth, load_gray, DepthMap};
use vofront::pipeline::{depth_plane, gray_plane, FeaturePose, FeatureTracker};

use crate::args::{Method, TwoViewArgs};

/// Most match lines drawn in `matches.png`.
const MAX_MATCH_LINES: usize = 250;

/// What the estimators get.
pub struct Inputs {
    /// Frame 1, grey.
    pub img1: GrayImage,
    /// Frame 2, grey.
    pub img2: GrayImage,
    /// Metric depth of frame 1, enabling SE(3) direct alignment.
    pub depth1: Option<DepthMap>,
    /// Camera of both frames.
    pub camera: Camera,
    /// Which estimators run.
    pub method: Method,
    /// ORB budget per image.
    pub features: usize,
}

/// A direct estimate with its wall-clock time in milliseconds.
pub type Timed<T> = (T, f64);

/// Each estimator's result or error message; `None` where it did not run.
pub struct Outcome {
    /// Feature-based relative pose.
    pub feature: Option<Result<FeaturePose, String>>,
    /// Direct 2D translation.
    pub translation: Option<Result<Timed<TranslationResult>, String>>,
    /// Direct SE(3) alignment with the depth of frame 1.
    pub se3: Option<Result<Timed<Se3Result>, String>>,
    /// The reference frame (undistorted image and depth of frame 1) `se3` was aligned against.
    pub se3_reference: Option<RgbdFrame>,
}

impl Outcome {
    /// True when at least one estimator produced an estimate.
    pub fn any_estimate(&self) -> bool {
        matches!(self.feature, Some(Ok(_)))
            || matches!(self.translation, Some(Ok(_)))
            || matches!(self.se3, Some(Ok(_)))
    }
}

fn timed<T, E: std::fmt::Display>(f: impl FnOnce() -> Result<T, E>) -> Result<Timed<T>, String> {
    let start = Instant::now();
    let out = f().map_err(|e| e.to_string())?;
    Ok((out, start.elapsed().as_secs_f64() * 1e3))
}

fn check_same_size(a: &GrayImage, b: (u32, u32), what: &str) -> Result<(), String> {
    if a.dimensions() == b {
        Ok(())
    } else {
        Err(format!(
            "image size {}x{} differs from {what} size {}x{}",
            a.width(),
            a.height(),
            b.0,
            b.1
        ))
    }
}

/// Runs the estimators `inputs.method` asks for; each fails on its own.
pub fn estimate(inputs: &Inputs) -> Outcome {
    let run_feature = inputs.method != Method::Direct;
    let run_direct = inputs.method != Method::Feature;
    let feature = run_feature.then(|| {
        FeatureTracker::with_features(inputs.features)
            .relative_pose(&inputs.img1, &inputs.img2, &inputs.camera)
            .map_err(|e| e.to_string())
    });
    let translation = run_direct.then(|| {
        check_same_size(&inputs.img1, inputs.img2.dimensions(), "frame 2")?;
        let (p1, p2) = (gray_plane(&inputs.img1), gray_plane(&inputs.img2));
        timed(|| align_translation(&p1, &p2, &TranslationConfig::default()))
    });
    let mut se3_reference = None;
    let se3 = run_direct
        .then_some(())
        .and(inputs.depth1.as_ref())
        .map(|depth| {
            check_same_size(&inputs.img1, inputs.img2.dimensions(), "frame 2")?;
            check_same_size(&inputs.img1, depth.dimensions(), "depth")?;
            let current = gray_plane(&inputs.img2);
            let ((fit, reference), ms) = timed(|| {
                let reference =
                    RgbdFrame::new(gray_plane(&inputs.img1), depth_plane(depth), &inputs.camera)?;
                let prior = Isometry3::identity();
                let fit = align_se3(&reference, &current, &prior, &Se3Config::default())?;
                Ok::<_, DirectError>((fit, reference))
            })?;
            se3_reference = Some(reference);
            Ok((fit, ms))
        });
    Outcome {
        feature,
        translation,
        se3,
        se3_reference,
    }
}

fn rows(m: &Matrix3<f64>) -> Value {
    json!([
        [m[(0, 0)], m[(0, 1)], m[(0, 2)]],
        [m[(1, 0)], m[(1, 1)], m[(1, 2)]],
        [m[(2, 0)], m[(2, 1)], m[(2, 2)]]
    ])
}

fn rotation_matrix(pose: &Isometry3<f64>) -> Matrix3<f64> {
    pose.rotation.to_rotation_matrix().into_inner()
}

fn or_error<T>(r: &Result<T, String>, f: impl FnOnce(&T) -> Value) -> Value {
    match r {
        Ok(v) => f(v),
        Err(e) => json!({ "error": e }),
    }
}

/// The JSON object of the public interface: keys `feature`, `direct_translation`, `direct_se3`.
pub fn to_json(outcome: &Outcome) -> Value {
    let mut out = serde_json::Map::new();
    if let Some(r) = &outcome.feature {
        out.insert("feature".into(), or_error(r, |f| {
            let e = &f.estimate;
            let t = e.translation;
            json!({
                "R": rows(&rotation_matrix(&e.pose)),
                "t": [t.x, t.y, t.z],
                "keypoints": [f.features[0].len(), f.features[1].len()],
                "matches": f.matches.len(),
                "inliers": e.inlier_count,
                "model": match e.model { Model::Essential => "essential", Model::Homography => "homography" },
                "parallax_deg": e.parallax_deg,
                "ms": {"detect": f.timings.detect, "match": f.timings.matching,
                       "estimate": f.timings.estimate, "total": f.timings.total},
            })
        }));
    }
    if let Some(r) = &outcome.translation {
        out.insert("direct_translation".into(), or_error(r, |(d, ms)| {
            json!({"d": [d.d.x, d.d.y], "iterations": d.iterations.iter().sum::<usize>(), "rmse": d.rmse, "ms": ms})
        }));
    }
    if let Some(r) = &outcome.se3 {
        out.insert("direct_se3".into(), or_error(r, |(s, ms)| {
            let t = s.pose.translation.vector;
            json!({"R": rows(&rotation_matrix(&s.pose)), "t": [t.x, t.y, t.z], "a": s.a, "b": s.b,
                   "inlier_ratio": s.inlier_ratio, "rmse": s.rmse, "ms": ms})
        }));
    }
    Value::Object(out)
}

/// Human-readable report, one block per estimator, with what its quality numbers mean.
pub fn print_text(outcome: &Outcome) {
    if let Some(r) = &outcome.feature {
        match r {
            Ok(f) => {
                let e = &f.estimate;
                let (rot, t) = (e.rotation.scaled_axis().map(f64::to_degrees), e.translation);
                outln!(
                    "feature     {:?} model, {} + {} keypoints, {} matches, {} inliers ({:.0}%)",
                    e.model,
                    f.features[0].len(),
                    f.features[1].len(),
                    f.matches.len(),
                    e.inlier_count,
                    100.0 * e.inlier_count as f64 / f.matches.len().max(1) as f64
                );
                outln!("            rotation vector {:+.3} {:+.3} {:+.3} deg, translation direction {:+.3} {:+.3} {:+.3}",
                    rot.x, rot.y, rot.z, t.x, t.y, t.z);
                outln!(
                    "            median parallax {:.2} deg{}",
                    e.parallax_deg,
                    if e.low_parallax {
                        " (too low: translation undetermined)"
                    } else {
                        ""
                    }
                );
                let ms = f.timings;
                outln!(
                    "            {:.1} ms (detect {:.1}, match {:.1}, estimate {:.1})",
                    ms.total,
                    ms.detect,
                    ms.matching,
                    ms.estimate
                );
            }
            Err(e) => outln!("feature     failed: {e}"),
        }
    }
    if let Some(r) = &outcome.translation {
        match r {
            Ok((d, ms)) => outln!(
                "direct 2D   shift d = ({:+.3}, {:+.3}) px with I2(x + d) = I1(x); rmse {:.2} grey levels, sigma ({:.3}, {:.3}) px, {} iterations{}, {:.1} ms",
                d.d.x, d.d.y, d.rmse, d.covariance[(0, 0)].sqrt(), d.covariance[(1, 1)].sqrt(),
                d.iterations.iter().sum::<usize>(),
                if d.converged { "" } else { " (not converged: a 2D shift does not explain this pair)" },
                ms),
            Err(e) => outln!("direct 2D   failed: {e}"),
        }
    }
    if let Some(r) = &outcome.se3 {
        match r {
            Ok((s, ms)) => {
                let (rot, t) = (
                    s.pose.rotation.scaled_axis().map(f64::to_degrees),
                    s.pose.translation.vector,
                );
                outln!("direct SE3  rotation vector {:+.3} {:+.3} {:+.3} deg, translation {:+.4} {:+.4} {:+.4} m",
                    rot.x, rot.y, rot.z, t.x, t.y, t.z);
                outln!("            brightness a {:.3} b {:+.2}; rmse {:.2} grey levels, {:.0}% inliers of {} pixels, {:.1} ms",
                    s.a, s.b, s.rmse, 100.0 * s.inlier_ratio, s.valid_pixels, ms);
            }
            Err(e) => outln!("direct SE3  failed: {e}"),
        }
    }
}

fn save(img: &image::RgbImage, dir: &Path, name: &str) -> Result<(), String> {
    img.save(dir.join(name))
        .map_err(|e| format!("cannot write {}: {e}", dir.join(name).display()))
}

/// Absolute difference `|I1(x) - I2(x + d)|` (NaN where `x + d` leaves frame 2).
fn shifted_difference(img1: &GrayImage, img2: &GrayImage, d: (f32, f32)) -> Vec<f32> {
    let (p1, p2) = (gray_plane(img1), gray_plane(img2));
    let (w, h) = p1.size();
    (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| {
            p2.sample(x as f32 + d.0, y as f32 + d.1)
                .map_or(f32::NAN, |v| (p1.at(x, y) - v).abs())
        })
        .collect()
}

/// Writes the pictures of every estimator that succeeded into `dir`.
pub fn write_pictures(dir: &Path, inputs: &Inputs, outcome: &Outcome) -> Result<(), String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
    if let Some(Ok(f)) = &outcome.feature {
        for (k, (img, feats)) in [
            (&inputs.img1, &f.features[0]),
            (&inputs.img2, &f.features[1]),
        ]
        .into_iter()
        .enumerate()
        {
            let points: Vec<_> = (0..feats.len())
                .map(|i| (feats.xs[i], feats.ys[i], feats.scales[i]))
                .collect();
            save(
                &draw::keypoints(img, &points),
                dir,
                &format!("keypoints{}.png", k + 1),
            )?;
        }
        let [f1, f2] = &f.features;
        // Every k-th match, so that about MAX_MATCH_LINES lines stay readable.
        let step = f.matches.len().div_ceil(MAX_MATCH_LINES).max(1);
        let pairs: Vec<_> = f
            .matches
            .iter()
            .zip(&f.estimate.inliers)
            .step_by(step)
            .map(|(m, &inlier)| {
                let (q, t) = (m.query as usize, m.train as usize);
                ((f1.xs[q], f1.ys[q]), (f2.xs[t], f2.ys[t]), inlier)
            })
            .collect();
        let e = &f.estimate;
        let caption = [
            format!(
                "{} matches, {} inliers (green), {} outliers (red); model: {:?}",
                f.matches.len(),
                e.inlier_count,
                f.matches.len() - e.inlier_count,
                e.model
            ),
            format!(
                "{} + {} keypoints; median parallax {:.2} deg; {} of the matches drawn",
                f1.len(),
                f2.len(),
                e.parallax_deg,
                pairs.len()
            ),
        ];
        let picture = draw::matches(&inputs.img1, &inputs.img2, &pairs);
        save(&draw::with_caption(&picture, &caption), dir, "matches.png")?;
    }
    if let Some(Ok((d, _))) = &outcome.translation {
        let (w, h) = inputs.img1.dimensions();
        let before = shifted_difference(&inputs.img1, &inputs.img2, (0.0, 0.0));
        let after = shifted_difference(&inputs.img1, &inputs.img2, (d.d.x as f32, d.d.y as f32));
        save(&draw::heat(w, h, &before, 64.0), dir, "diff_before.png")?;
        save(&draw::heat(w, h, &after, 64.0), dir, "diff_after.png")?;
    }
    if let (Some(Ok((s, _))), Some(reference)) = (&outcome.se3, &outcome.se3_reference) {
        let map = photometric_residual_map(reference, &gray_plane(&inputs.img2), &s.pose, s.a, s.b)
            .map_err(|e| e.to_string())?;
        let (w, h) = map.size();
        save(
            &draw::heat(
                w as u32,
                h as u32,
                &map.data,
                (4.0 * s.rmse as f32).max(8.0),
            ),
            dir,
            "residual_se3.png",
        )?;
    }
    Ok(())
}

/// Runs `vofront two-view`; `Ok(false)` when no estimator produced an estimate.
pub fn run(args: &TwoViewArgs) -> Result<bool, String> {
    let camera = args.camera.camera()?;
    let img1 = load_gray(&args.img1).map_err(|e| e.to_string())?;
    if let Some(warning) = args.camera.default_camera_warning(img1.dimensions()) {
        eprintln!("vofront: warning: {warning}");
    }
    let img2 = load_gray(&args.img2).map_err(|e| e.to_string())?;
    let depth1 = match &args.depth1 {
        Some(p) => Some(load_depth(p, args.depth_scale).map_err(|e| e.to_string())?),
        None => None,
    };
    let inputs = Inputs {
        img1,
        img2,
        depth1,
        camera,
        method: args.method,
        features: args.features,
    };
    let outcome = estimate(&inputs);
    if args.json {
        outln!("{}", to_json(&outcome));
    } else {
        print_text(&outcome);
    }
    if let Some(dir) = &args.out_dir {
        write_pictures(dir, &inputs, &outcome)?;
    }
    Ok(outcome.any_estimate())
}
