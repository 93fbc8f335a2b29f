//! `vofront odometry DATASET`: track a whole sequence, write the TUM trajectory, per-frame
//! metrics and a plot, and print a summary (with ATE when the dataset has ground truth).

use std::io::IsTerminal;
use std::path::Path;

use indicatif::{ProgressBar, ProgressStyle};
use vofront::dataset::{tum::tum_preset_for, Dataset, DatasetKind};
use vofront::eval::{ate, plot::write_plot, Alignment, EvalConfig};
use vofront::geometry::Camera;
use vofront::odometry::direct::{DirectTracker, DirectTrackerConfig};
use vofront::odometry::feature_rgbd::{FeatureRgbdConfig, FeatureRgbdTracker};
use vofront::odometry::mono::{MonoConfig, MonoTracker};
use vofront::odometry::run::{run as run_tracker, write_metrics_csv, RunOutput, RunSummary};
use vofront::odometry::Tracker;

use crate::args::{OdometryArgs, OdometryMethod};

/// Exit code when tracking was lost for good (partial results are still written).
pub const EXIT_LOST: u8 = 3;

/// The camera: explicit flags first, then the dataset's calibration, then a TUM preset
/// recognised from the folder name, then the ROS default.
fn choose_camera(args: &OdometryArgs, dataset: &Dataset) -> Result<Camera, String> {
    if args.camera.is_given() {
        return args.camera.camera();
    }
    if let Some(camera) = dataset.camera {
        return Ok(camera);
    }
    if dataset.kind == DatasetKind::Tum {
        if let Some(camera) = tum_preset_for(&dataset.root) {
            return Ok(camera);
        }
    }
    args.camera.camera()
}

/// The tracker a method names.
pub fn make_tracker(method: OdometryMethod, camera: Camera) -> Result<Box<dyn Tracker>, String> {
    Ok(match method {
        OdometryMethod::Direct => {
            Box::new(DirectTracker::new(camera, DirectTrackerConfig::default()))
        }
        OdometryMethod::FeatureRgbd => Box::new(
            FeatureRgbdTracker::new(camera, FeatureRgbdConfig::default())
                .map_err(|e| e.to_string())?,
        ),
        OdometryMethod::Feature => {
            Box::new(MonoTracker::new(camera, MonoConfig::default()).map_err(|e| e.to_string())?)
        }
    })
}

/// Tracks `dataset` with `tracker`, a progress bar on stderr when it is a terminal.
pub fn track(dataset: &Dataset, tracker: &mut dyn Tracker, max_frames: Option<usize>) -> RunOutput {
    let total = max_frames.map_or(dataset.len(), |m| m.min(dataset.len()));
    let bar = std::io::stderr().is_terminal().then(|| {
        let bar = ProgressBar::new(total as u64);
        bar.set_style(
            ProgressStyle::with_template("{bar:40} {pos}/{len} frames, {per_sec}, eta {eta}")
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        bar
    });
    let out = run_tracker(dataset, tracker, max_frames, |done, _| {
        if let Some(bar) = &bar {
            bar.set_position(done as u64);
        }
    });
    if let Some(bar) = bar {
        bar.finish_and_clear();
    }
    out
}

/// The alignment a method's trajectory is evaluated with: monocular scale is arbitrary.
pub fn alignment_for(method: OdometryMethod) -> Alignment {
    if method == OdometryMethod::Feature {
        Alignment::Sim3
    } else {
        Alignment::Se3
    }
}

/// Prints the summary lines and, with ground truth, the ATE; writes the plot if asked.
pub fn report(
    dataset: &Dataset,
    out: &RunOutput,
    alignment: Alignment,
    plot: Option<&Path>,
) -> Result<(), String> {
    let s = &out.summary;
    outln!(
        "frames {}, tracked {}, lost {}, reinitialised {}, unreadable {}, keyframes {}, {:.1} ms per frame ({:.0} frames/s)",
        s.frames, out.trajectory.len(), s.lost, s.reinitialised, s.unreadable, s.keyframes, s.mean_ms,
        1e3 / s.mean_ms.max(1e-9)
    );
    let Some(gt) = &dataset.ground_truth else {
        if plot.is_some() {
            eprintln!("vofront: no ground truth in the dataset, no plot written");
        }
        return Ok(());
    };
    let cfg = EvalConfig {
        alignment,
        max_dt: dataset.ground_truth_tolerance,
    };
    match ate(gt, &out.trajectory, &cfg) {
        Ok(a) => {
            outln!(
                "ATE rmse {:.4} m over {} poses ({alignment:?}-aligned)",
                a.stats.rmse,
                a.pairs.len()
            );
            if let Some(path) = plot {
                write_plot(path, gt, &a.aligned, &a.errors)
                    .map_err(|e| format!("{}: {e}", path.display()))?;
            }
        }
        Err(e) => outln!("ATE not computed: {e}"),
    }
    Ok(())
}

/// Runs `vofront odometry`; `Ok(true)` when tracking was lost for good.
pub fn run(args: &OdometryArgs) -> Result<bool, String> {
    let dataset = Dataset::open(&args.dataset).map_err(|e| e.to_string())?;
    let camera = choose_camera(args, &dataset)?;
    if args.method != OdometryMethod::Feature && dataset.frames.iter().all(|f| f.depth.is_none()) {
        return Err(format!(
            "{}: the {:?} method needs depth, and this dataset has none",
            args.dataset.display(),
            args.method
        ));
    }
    let mut tracker = make_tracker(args.method, camera)?;
    let out = track(&dataset, tracker.as_mut(), args.max_frames);
    out.trajectory
        .write_tum(&args.out)
        .map_err(|e| e.to_string())?;
    if let Some(path) = &args.metrics {
        write_metrics_csv(path, &out.records).map_err(|e| format!("{}: {e}", path.display()))?;
    }
    report(
        &dataset,
        &out,
        alignment_for(args.method),
        args.plot.as_deref(),
    )?;
    Ok(RunSummary::lost_for_good(&out.records))
}
