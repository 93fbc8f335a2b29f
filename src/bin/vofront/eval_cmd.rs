//! `vofront eval GT EST`: ATE and RPE of an estimated trajectory, as evo computes them.

use std::fs;
use std::path::{Path, PathBuf};

use serde::Serialize;
use vofront::eval::plot::{write_eval_plots, write_plot, PlotFormat};
use vofront::eval::{
    ate, rpe_with, Alignment, DeltaUnit, EvalConfig, RotationScale, RpeConfig, Stats,
};
use vofront::trajectory::{pair_untimed, Trajectory, TrajectoryFile, TrajectoryFormat};

use crate::args::{AlignArg, DeltaUnitArg, EvalArgs, FormatArg};

/// The `--json` summary (keys are public: add, don't rename).
#[derive(Serialize)]
struct Summary {
    /// Associated pose pairs.
    pairs: usize,
    alignment: &'static str,
    scale: f64,
    ate: Stats,
    rpe: RpeSummary,
    /// Pictures written (`--plot`, `--plot-dir`).
    plots: Vec<PathBuf>,
}

#[derive(Serialize)]
struct RpeSummary {
    delta: f64,
    delta_unit: &'static str,
    all_pairs: bool,
    /// Compared pose pairs.
    pairs: usize,
    translation: Stats,
    rotation_deg: Stats,
    /// `{"scale", "sigma"}`: estimated over true rotation (`null` without true rotation).
    rotation_scale: Option<RotationScale>,
}

fn unit(arg: DeltaUnitArg) -> DeltaUnit {
    match arg {
        DeltaUnitArg::Frames => DeltaUnit::Frames,
        DeltaUnitArg::Meters => DeltaUnit::Meters,
        DeltaUnitArg::Seconds => DeltaUnit::Seconds,
    }
}

/// Reads the ground truth and the estimate in their formats (flags, else detected), with
/// their KITTI times (`--times` stamps whichever of the two is KITTI), matched by index when
/// one has no timestamps.
fn read_pair(args: &EvalArgs) -> Result<(Trajectory, Trajectory), String> {
    let read = |path: &Path, format: Option<FormatArg>, times: Option<&PathBuf>| {
        let format = match format.or(args.format) {
            Some(f) => f.format(),
            None => {
                let text =
                    fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
                TrajectoryFormat::detect(&text).unwrap_or(TrajectoryFormat::Tum)
            }
        };
        let times = times.or(args
            .times
            .as_ref()
            .filter(|_| format == TrajectoryFormat::Kitti));
        TrajectoryFile::read(path, Some(format), times.map(PathBuf::as_path))
            .map_err(|e| e.to_string())
    };
    let gt = read(&args.gt, args.ref_format, args.ref_times.as_ref())?;
    let est = read(&args.est, args.est_format, args.est_times.as_ref())?;
    pair_untimed(gt, est).map_err(|e| e.to_string())
}

/// Runs `vofront eval`; an error message on failure.
pub fn run(args: &EvalArgs) -> Result<(), String> {
    let (gt, est) = read_pair(args)?;
    let (alignment, alignment_name) = match args.align {
        AlignArg::None => (Alignment::None, "none"),
        AlignArg::Se3 => (Alignment::Se3, "se3"),
        AlignArg::Sim3 => (Alignment::Sim3, "sim3"),
    };
    let cfg = EvalConfig {
        max_dt: args.max_dt,
        alignment,
    };
    let ate = ate(&gt, &est, &cfg).map_err(|e| format!("ATE: {e}"))?;
    let rpe_cfg = cfg.for_rpe();
    let pairs = RpeConfig {
        delta: args.delta,
        unit: unit(args.delta_unit),
        all_pairs: args.all_pairs,
        delta_tol: args.delta_tol,
        pairs_from_reference: args.pairs_from_reference,
    };
    let rpe = rpe_with(&gt, &est, &rpe_cfg, &pairs).map_err(|e| format!("RPE: {e}"))?;
    let mut plots = Vec::new();
    if let Some(path) = &args.plot {
        write_plot(path, &gt, &ate.aligned, &ate.errors)
            .map_err(|e| format!("{}: {e}", path.display()))?;
        plots.push(path.clone());
    }
    if let Some(dir) = &args.plot_dir {
        let format = if args.svg {
            PlotFormat::Svg
        } else {
            PlotFormat::Png
        };
        let written = write_eval_plots(dir, format, &gt, &ate, &rpe)
            .map_err(|e| format!("{}: {e}", dir.display()))?;
        plots.extend(written);
    }
    let unit_name = pairs.unit.symbol();
    if args.json {
        let summary = Summary {
            pairs: ate.pairs.len(),
            alignment: alignment_name,
            scale: ate.alignment.scale,
            ate: ate.stats,
            rpe: RpeSummary {
                delta: args.delta,
                delta_unit: unit_name,
                all_pairs: args.all_pairs,
                pairs: rpe.delta_pairs.len(),
                translation: rpe.translation,
                rotation_deg: rpe.rotation_deg,
                rotation_scale: rpe.rotation_scale,
            },
            plots,
        };
        let text = serde_json::to_string(&summary).map_err(|e| e.to_string())?;
        outln!("{text}");
        return Ok(());
    }
    outln!("associated poses   {}", ate.pairs.len());
    outln!(
        "alignment          {alignment_name} (scale {:.6})",
        ate.alignment.scale
    );
    outln!(
        "ATE rmse           {:.6} m  (mean {:.6}, median {:.6}, max {:.6})",
        ate.stats.rmse,
        ate.stats.mean,
        ate.stats.median,
        ate.stats.max
    );
    let per = format!(
        "per {} {unit_name}{}, {} pairs",
        args.delta,
        if args.all_pairs { ", all pairs" } else { "" },
        rpe.delta_pairs.len()
    );
    outln!("RPE trans rmse     {:.6} m {per}", rpe.translation.rmse);
    outln!("RPE rot rmse       {:.6} deg {per}", rpe.rotation_deg.rmse);
    if let Some(r) = rpe.rotation_scale {
        outln!(
            "RPE rot scale      {:.6} +- {:.6} (estimated / true rotation; 1 = consistent)",
            r.scale,
            r.sigma
        );
    }
    for p in &plots {
        outln!("wrote              {}", p.display());
    }
    Ok(())
}
