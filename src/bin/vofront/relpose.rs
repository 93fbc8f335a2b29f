//! `vofront relpose MATCHES.csv`: robust relative pose from correspondences found elsewhere.

use std::time::Instant;

use serde_json::json;
use vofront::geometry::{estimate_relative_pose, RelativePoseConfig};
use vofront::input::load_correspondences;

use crate::args::RelposeArgs;

/// Runs `vofront relpose`, printing `{"R", "t", "inliers", "ms"}`.
pub fn run(args: &RelposeArgs) -> Result<(), String> {
    let camera = args.camera.camera()?;
    let c = load_correspondences(&args.matches).map_err(|e| e.to_string())?;
    let start = Instant::now();
    let fit = estimate_relative_pose(&c.x1, &c.x2, &camera, &RelativePoseConfig::default())
        .map_err(|e| format!("{}: {e}", args.matches.display()))?;
    let ms = start.elapsed().as_secs_f64() * 1e3;
    let r = fit.pose.rotation.to_rotation_matrix().into_inner();
    let t = fit.translation;
    let out = json!({
        "R": [[r[(0, 0)], r[(0, 1)], r[(0, 2)]], [r[(1, 0)], r[(1, 1)], r[(1, 2)]], [r[(2, 0)], r[(2, 1)], r[(2, 2)]]],
        "t": [t.x, t.y, t.z],
        "inliers": fit.inlier_count,
        "ms": ms,
    });
    outln!("{out}");
    Ok(())
}
