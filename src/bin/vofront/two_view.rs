//! `vofront two-view`: feature and direct estimates of one frame pair, as text or JSON, with
//! pictures. The estimation lives in [`vofront::two_view`], the JSON in
//! [`vofront::report::two_view`]; the demo
//! reuses [`print_text`] and [`write_pictures`].

use std::path::Path;

use vofront::direct::photometric_residual_map;
use vofront::draw;
use vofront::image::Image;
use vofront::input::{load_depth, load_gray};
use vofront::report::two_view::to_json;
use vofront::robust::Quality;
use vofront::two_view::stereo::StereoFirst;
pub use vofront::two_view::{estimate, Inputs, Outcome, Status};

use crate::args::TwoViewArgs;

/// Most match lines drawn in `matches.png`.
const MAX_MATCH_LINES: usize = 250;

/// `verdict ok` or `verdict unreliable (low_parallax, ...)`, then the sigmas the record has.
pub fn verdict_line(q: &Quality) -> String {
    let mut line = format!("verdict {}", q.verdict);
    if !q.reasons.is_empty() {
        let names: Vec<&str> = q.reasons.iter().map(|r| r.name()).collect();
        line += &format!(" ({})", names.join(", "));
    }
    let u = &q.uncertainty;
    let sigmas = [
        u.rotation_sigma_deg
            .map(|s| format!("rotation sigma {s:.3} deg")),
        u.translation_direction_sigma_deg
            .map(|s| format!("translation direction sigma {s:.2} deg")),
        u.translation_sigma_m
            .map(|s| format!("translation sigma {:.1} mm", s * 1e3)),
        u.shift_sigma_px.map(|s| format!("shift sigma {s:.3} px")),
    ];
    for s in sigmas.into_iter().flatten() {
        line += &format!("; {s}");
    }
    line
}

/// Human-readable report, one block per estimator, with what its quality numbers mean.
pub fn print_text(outcome: &Outcome) {
    if let Some(r) = &outcome.feature {
        match r {
            Ok(f) => {
                let e = &f.estimate;
                let (rot, t) = (
                    e.rotation().scaled_axis().map(f64::to_degrees),
                    e.translation(),
                );
                outln!(
                    "feature     {:?} model, {} + {} keypoints, {} matches, {} inliers ({:.0}%)",
                    e.model,
                    f.features[0].len(),
                    f.features[1].len(),
                    f.matches.len(),
                    e.inlier_count(),
                    100.0 * e.inlier_count() as f64 / f.matches.len().max(1) as f64
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
                outln!("            {}", verdict_line(&e.quality));
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
    if let Some(r) = &outcome.feature_stereo {
        match r {
            Ok(s) => {
                let (rot, t) = (
                    s.pnp.pose.rotation.scaled_axis().map(f64::to_degrees),
                    s.pnp.pose.translation.vector,
                );
                let inliers = s.pnp.inliers.iter().filter(|&&i| i).count();
                outln!(
                    "stereo      {} + {} keypoints, {} with a stereo point, {} matched in frame 2, {} PnP inliers, rmse {:.2} px",
                    s.keypoints[0], s.keypoints[1], s.stereo_points, s.matches, inliers, s.pnp.rmse_px
                );
                outln!("            rotation vector {:+.3} {:+.3} {:+.3} deg, translation {:+.4} {:+.4} {:+.4} m",
                    rot.x, rot.y, rot.z, t.x, t.y, t.z);
                outln!("            {}", verdict_line(&s.pnp.quality));
                outln!("            {:.1} ms", s.ms);
            }
            Err(e) => outln!("stereo      failed: {e}"),
        }
    }
    if let Some(r) = &outcome.translation {
        match r {
            Ok((d, ms)) => {
                outln!(
                    "direct 2D   shift d = ({:+.3}, {:+.3}) px with I2(x + d) = I1(x); rmse {:.2} grey levels, sigma {} px, {} iterations{}, {:.1} ms",
                    d.d.x, d.d.y, d.rmse,
                    d.covariance.map_or("unknown".to_string(), |c| format!("({:.3}, {:.3})", c[(0, 0)].sqrt(), c[(1, 1)].sqrt())),
                    d.iterations.iter().sum::<usize>(),
                    if d.converged { "" } else { " (not converged: a 2D shift does not explain this pair)" },
                    ms);
                outln!("            {}", verdict_line(&d.quality));
            }
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
                outln!("            {}", verdict_line(&s.quality));
            }
            Err(e) => outln!("direct SE3  failed: {e}"),
        }
    }
    if let Some(rec) = &outcome.report().recommended {
        match rec.estimate {
            Some(name) => outln!("recommended {name}: {}", rec.why),
            None => outln!("recommended none: {}", rec.why),
        }
    }
}

fn save(img: &image::RgbImage, dir: &Path, name: &str) -> Result<(), String> {
    img.save(dir.join(name))
        .map_err(|e| format!("cannot write {}: {e}", dir.join(name).display()))
}

/// Absolute difference `|I1(x) - I2(x + d)|` (NaN where `x + d` leaves frame 2).
fn shifted_difference(img1: &Image<u8>, img2: &Image<u8>, d: (f32, f32)) -> Vec<f32> {
    let (p1, p2) = (img1.to_f32(), img2.to_f32());
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
                .map(|i| (feats.xs()[i], feats.ys()[i], feats.scales()[i]))
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
                ((f1.xs()[q], f1.ys()[q]), (f2.xs()[t], f2.ys()[t]), inlier)
            })
            .collect();
        let e = &f.estimate;
        let caption = [
            format!(
                "{} matches, {} inliers (green), {} outliers (red); model: {:?}",
                f.matches.len(),
                e.inlier_count(),
                f.matches.len() - e.inlier_count(),
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
        let (w, h) = (inputs.img1.width() as u32, inputs.img1.height() as u32);
        let before = shifted_difference(&inputs.img1, &inputs.img2, (0.0, 0.0));
        let after = shifted_difference(&inputs.img1, &inputs.img2, (d.d.x as f32, d.d.y as f32));
        save(&draw::heat(w, h, &before, 64.0), dir, "diff_before.png")?;
        save(&draw::heat(w, h, &after, 64.0), dir, "diff_after.png")?;
    }
    if let (Some(Ok((s, _))), Some(reference)) = (&outcome.se3, &outcome.se3_reference) {
        let map = photometric_residual_map(reference, &inputs.img2.to_f32(), &s.pose, s.a, s.b)
            .map_err(|e| e.to_string())?;
        let (w, h) = map.size();
        save(
            &draw::heat(
                w as u32,
                h as u32,
                map.data(),
                (4.0 * s.rmse as f32).max(8.0),
            ),
            dir,
            "residual_se3.png",
        )?;
    }
    Ok(())
}

/// Runs `vofront two-view`; the status decides the exit code (0, 4 or 1).
pub fn run(args: &TwoViewArgs) -> Result<Status, String> {
    let camera = args.camera.camera()?;
    let img1 = load_gray(&args.img1).map_err(|e| e.to_string())?;
    if let Some(warning) = args.camera.default_camera_warning(img1.size()) {
        eprintln!("vofront: warning: {warning}");
    }
    let img2 = load_gray(&args.img2).map_err(|e| e.to_string())?;
    let depth1 = match &args.depth1 {
        Some(p) => Some(load_depth(p, args.depth_scale).map_err(|e| e.to_string())?),
        None => None,
    };
    let stereo = match (&args.right1, args.baseline) {
        (Some(p), Some(baseline)) => Some(StereoFirst {
            right1: load_gray(p).map_err(|e| e.to_string())?,
            baseline,
        }),
        _ => None,
    };
    let inputs = Inputs {
        img1,
        img2,
        depth1,
        camera,
        method: args.method,
        features: args.features,
        stereo,
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
    Ok(outcome.status())
}
