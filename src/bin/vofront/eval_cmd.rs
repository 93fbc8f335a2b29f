//! `vofront eval GT EST`: ATE and RPE of an estimated trajectory, as evo computes them.

use serde_json::{json, Value};
use vofront::eval::{ate, plot::write_plot, rpe, Alignment, EvalConfig, Stats};
use vofront::trajectory::Trajectory;

use crate::args::{AlignArg, EvalArgs};

/// Evo-style statistics as a JSON object.
pub(crate) fn stats_json(s: &Stats) -> Value {
    json!({"rmse": s.rmse, "mean": s.mean, "median": s.median, "std": s.std,
           "min": s.min, "max": s.max, "count": s.count})
}

/// Runs `vofront eval`; an error message on failure.
pub fn run(args: &EvalArgs) -> Result<(), String> {
    let gt = Trajectory::read_tum(&args.gt).map_err(|e| e.to_string())?;
    let est = Trajectory::read_tum(&args.est).map_err(|e| e.to_string())?;
    let alignment = match args.align {
        AlignArg::None => Alignment::None,
        AlignArg::Se3 => Alignment::Se3,
        AlignArg::Sim3 => Alignment::Sim3,
    };
    let cfg = EvalConfig {
        max_dt: args.max_dt,
        alignment,
    };
    let ate = ate(&gt, &est, &cfg).map_err(|e| format!("ATE: {e}"))?;
    // RPE is invariant to a rigid alignment; a similarity rescales its translation part.
    let rpe_cfg = EvalConfig {
        alignment: if alignment == Alignment::Sim3 {
            Alignment::Sim3
        } else {
            Alignment::None
        },
        ..cfg
    };
    let rpe = rpe(&gt, &est, &rpe_cfg).map_err(|e| format!("RPE: {e}"))?;
    if let Some(path) = &args.plot {
        write_plot(path, &gt, &ate.aligned, &ate.errors)
            .map_err(|e| format!("{}: {e}", path.display()))?;
    }
    if args.json {
        let out = json!({
            "pairs": ate.pairs.len(),
            "alignment": format!("{:?}", args.align).to_lowercase(),
            "scale": ate.alignment.scale,
            "ate": stats_json(&ate.stats),
            "rpe": {"translation": stats_json(&rpe.translation), "rotation_deg": stats_json(&rpe.rotation_deg)},
        });
        outln!("{out}");
    } else {
        outln!("associated poses   {}", ate.pairs.len());
        outln!(
            "alignment          {:?} (scale {:.6})",
            args.align,
            ate.alignment.scale
        );
        outln!(
            "ATE rmse           {:.6} m  (mean {:.6}, median {:.6}, max {:.6})",
            ate.stats.rmse,
            ate.stats.mean,
            ate.stats.median,
            ate.stats.max
        );
        outln!("RPE trans rmse     {:.6} m per frame", rpe.translation.rmse);
        outln!(
            "RPE rot rmse       {:.6} deg per frame",
            rpe.rotation_deg.rmse
        );
    }
    Ok(())
}
