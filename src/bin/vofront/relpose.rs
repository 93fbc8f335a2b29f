//! `vofront relpose MATCHES.csv`: robust relative pose from correspondences found elsewhere.

use std::time::Instant;

use serde::Serialize;
use vofront::geometry::{estimate_relative_pose, RelativePoseConfig};
use vofront::input::load_correspondences;
use vofront::report::two_view::PoseReport;

use crate::args::RelposeArgs;

/// The JSON of `relpose`: the keys of two-view's `feature` object (`R`, `t`, `matches`,
/// `inliers`, `model`, `parallax_deg`, `quality`) and the estimation time `ms`.
#[derive(Serialize)]
struct RelposeReport {
    #[serde(flatten)]
    pose: PoseReport,
    ms: f64,
}

/// Runs `vofront relpose`, printing one JSON object; `Ok(false)` when the pose is not `ok`.
pub fn run(args: &RelposeArgs) -> Result<bool, String> {
    let camera = args.camera.camera()?;
    let c = load_correspondences(&args.matches).map_err(|e| e.to_string())?;
    let start = Instant::now();
    let fit = estimate_relative_pose(&c.x1, &c.x2, &camera, &RelativePoseConfig::default())
        .map_err(|e| format!("{}: {e}", args.matches.display()))?;
    let ms = start.elapsed().as_secs_f64() * 1e3;
    let report = RelposeReport {
        pose: PoseReport::new(&fit, c.x1.len()),
        ms,
    };
    let json = serde_json::to_string(&report).map_err(|e| e.to_string())?;
    outln!("{json}");
    Ok(fit.quality.is_ok())
}
