//! `vofront odometry DATASET`: track a whole sequence, streaming the TUM trajectory and the
//! per-frame metrics to disk as each frame finishes, and print a summary (text or `--json`,
//! with ATE and RPE when the dataset has ground truth).
//!
//! Output paths are checked (parent folders created, files opened) before the first frame.
//! SIGINT / SIGTERM stop the run after the frame in progress: the summary is still printed
//! and the exit code is [`EXIT_SIGINT`] / [`EXIT_SIGTERM`]; a second signal exits at once
//! (every finished frame is already on disk).

use std::fs::File;
use std::io::{BufWriter, IsTerminal};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;

use indicatif::{ProgressBar, ProgressStyle};
use vofront::core::{Camera, Lens};
use vofront::dataset::bag::write::PoseBagSink;
use vofront::dataset::{Dataset, DatasetConfig};
use vofront::eval::{plot::write_plot, AteResult};
use vofront::odometry::graph::G2oSink;
use vofront::odometry::registry::{Evaluation, Session, TrackerOptions};
use vofront::odometry::rerun_log::RerunSink;
use vofront::odometry::run::{
    run as run_tracker, FrameRecord, MetricsCsvSink, RunControl, RunOutput, RunSummary, TumSink,
};
use vofront::odometry::sink::KittiSink;
use vofront::odometry::Tracker;
use vofront::report::odometry::{OdometryReport, Outputs};

use crate::args::{DatasetArgs, OdometryArgs, OutFormat};

/// Exit code when tracking was lost for good (partial results are still written).
pub const EXIT_LOST: u8 = 3;
/// Exit code after SIGINT (128 + 2, as shells report it).
pub const EXIT_SIGINT: u8 = 130;
/// Exit code after SIGTERM (128 + 15).
pub const EXIT_SIGTERM: u8 = 143;

/// One line describing `camera`.
fn describe_camera(camera: &Camera) -> String {
    let (k, d) = (camera.pinhole, camera.distortion);
    let names = match d {
        Lens::RadialTangential(_) => "k1,k2,p1,p2,k3",
        Lens::KannalaBrandt(_) => "k1,k2,k3,k4",
    };
    let values: Vec<String> = d.coefficients().iter().map(f64::to_string).collect();
    format!(
        "fx {} fy {} cx {} cy {}, {} distortion {names} = {}",
        k.fx,
        k.fy,
        k.cx,
        k.cy,
        d.model_name(),
        values.join(",")
    )
}

/// A progress bar over `total` frames on stderr, when stderr is a terminal.
pub fn progress_bar(total: usize) -> Option<ProgressBar> {
    std::io::stderr().is_terminal().then(|| {
        let bar = ProgressBar::new(total as u64);
        bar.set_style(
            ProgressStyle::with_template("{bar:40} {pos}/{len} frames, {per_sec}, eta {eta}")
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        bar
    })
}

/// Tracks `dataset` with `tracker` in memory, a progress bar on stderr when it is a terminal.
pub fn track(dataset: &Dataset, tracker: &mut dyn Tracker, max_frames: Option<usize>) -> RunOutput {
    let total = max_frames.map_or(dataset.len(), |m| m.min(dataset.len()));
    let bar = progress_bar(total);
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

/// ATE and RPE of a run against the dataset's camera ground truth (EuRoC body poses turned
/// into camera poses); `None` without ground truth or without any frame.
fn evaluate(session: &Session, out: &RunOutput) -> Option<Evaluation> {
    if out.summary.frames == 0 {
        return None;
    }
    session.evaluate(&out.trajectory)
}

/// Writes the plot of the aligned trajectory against the ground truth.
fn plot(evaluation: &Evaluation, a: &AteResult, path: &Path) -> Result<(), String> {
    write_plot(path, &evaluation.ground_truth, &a.aligned, &a.errors)
        .map_err(|e| format!("{}: {e}", path.display()))
}

/// Prints the summary lines and, with ground truth, ATE and RPE; writes the plot if asked.
pub fn report(session: &Session, out: &RunOutput, plot_path: Option<&Path>) -> Result<(), String> {
    let s = &out.summary;
    match s.frames_per_second() {
        _ if s.frames == 0 => outln!("frames 0: nothing was tracked"),
        None => outln!("frames {}: none could be read, nothing was tracked", s.frames),
        Some(fps) => outln!(
            "frames {}, tracked {} (unreliable {}), lost {}, reinitialised {}, unreadable {}, keyframes {}, {:.1} ms per frame ({fps:.0} frames/s)",
            s.frames, out.trajectory.len(), s.unreliable, s.lost, s.reinitialised, s.unreadable, s.keyframes, s.mean_ms
        ),
    }
    let Some(evaluation) = evaluate(session, out) else {
        if plot_path.is_some() {
            eprintln!("vofront: no ground truth (or no frame), no plot written");
        }
        return Ok(());
    };
    match &evaluation.ate {
        Ok(a) => {
            outln!(
                "ATE rmse {:.4} m over {} poses ({:?}-aligned)",
                a.stats.rmse,
                a.pairs.len(),
                evaluation.alignment
            );
            if let Some(path) = plot_path {
                plot(&evaluation, a, path)?;
            }
        }
        Err(e) => outln!("ATE not computed: {e}"),
    }
    match &evaluation.rpe {
        Ok(r) => {
            outln!(
                "RPE rmse {:.4} m, {:.3} deg per frame",
                r.translation.rmse,
                r.rotation_deg.rmse
            );
            if let Some(k) = r.rotation_scale {
                outln!(
                    "rotation scale {:.4} +- {:.4} (estimated / true; 1 = consistent)",
                    k.scale,
                    k.sigma
                );
            }
        }
        Err(e) => outln!("RPE not computed: {e}"),
    }
    Ok(())
}

/// The `--json` summary ([`OdometryReport`], keys documented in the README); writes the plot
/// if asked.
fn report_json(
    args: &OdometryArgs,
    session: &Session,
    out: &RunOutput,
) -> Result<OdometryReport, String> {
    let evaluation = evaluate(session, out);
    if let (Some(e), Some(path)) = (&evaluation, &args.plot) {
        if let Ok(a) = &e.ate {
            plot(e, a, path)?;
        }
    }
    let outputs = Outputs {
        trajectory: args.out.display().to_string(),
        metrics: args.metrics.display().to_string(),
        graph: args.graph.as_ref().map(|p| p.display().to_string()),
        plot: args.plot.as_ref().map(|p| p.display().to_string()),
    };
    Ok(OdometryReport::new(
        session,
        out,
        evaluation.as_ref(),
        outputs,
    ))
}

/// Where `--out-format kitti` writes the timestamps of the poses in `out`: `<out>.times`.
fn kitti_times_path(out: &Path) -> PathBuf {
    let mut name = out.as_os_str().to_owned();
    name.push(".times");
    PathBuf::from(name)
}

/// Creates `path` for writing (and its missing parent folders), before any work is done.
pub fn create_output(path: &Path) -> Result<BufWriter<File>, String> {
    let fail = |e: std::io::Error| format!("{}: cannot write: {e}", path.display());
    if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent).map_err(fail)?;
    }
    File::create(path).map(BufWriter::new).map_err(fail)
}

/// The Rerun sink asked for by `--rerun FILE` or `--rerun-connect ADDR` (the file created
/// now), with the dataset's ground truth when it has one.
fn rerun_sink(args: &OdometryArgs, session: &Session) -> Result<Option<RerunSink>, String> {
    let sink = match (&args.rerun, &args.rerun_connect) {
        (Some(path), _) => RerunSink::save(path, session.camera),
        (None, Some(address)) => RerunSink::connect(address, session.camera),
        (None, None) => return Ok(None),
    }
    .map_err(|e| e.to_string())?;
    Ok(Some(match session.dataset.camera_ground_truth() {
        Some(gt) => sink.with_ground_truth(gt),
        None => sink,
    }))
}

/// The stop flag raised by the first SIGINT or SIGTERM, and the exit code it asks for
/// (0 until a signal arrives). A second signal exits at once with that signal's code.
pub fn install_signal_handlers() -> Result<(Arc<AtomicBool>, Arc<AtomicUsize>), String> {
    use signal_hook::consts::{SIGINT, SIGTERM};
    use signal_hook::flag;
    let stop = Arc::new(AtomicBool::new(false));
    let code = Arc::new(AtomicUsize::new(0));
    for (signal, exit) in [(SIGINT, EXIT_SIGINT), (SIGTERM, EXIT_SIGTERM)] {
        flag::register_conditional_shutdown(signal, i32::from(exit), Arc::clone(&stop))
            .and_then(|_| flag::register_usize(signal, Arc::clone(&code), usize::from(exit)))
            .and_then(|_| flag::register(signal, Arc::clone(&stop)))
            .map_err(|e| format!("cannot install the signal handlers: {e}"))?;
    }
    Ok((stop, code))
}

/// Opens the dataset folder or bag at `path` with the `--fps`, topic and `--depth-scale`
/// flags of `input` (each checked), printing the dataset's notes on stderr.
pub fn open_dataset(path: &Path, input: &DatasetArgs) -> Result<Dataset, String> {
    let (fps, topics, depth_scale) = (input.fps, &input.topics, input.depth_scale);
    if let Some(fps) = fps {
        if !(fps.is_finite() && fps > 0.0) {
            return Err(format!("--fps {fps}: must be a positive number"));
        }
    }
    let config = DatasetConfig {
        fps,
        ..DatasetConfig::default()
    };
    let mut dataset = if path.is_file() || topics.is_given() {
        Dataset::open_bag(path, &config, &topics.topics())
    } else {
        Dataset::open_with(path, &config)
    }
    .map_err(|e| e.to_string())?;
    for note in dataset.notes() {
        eprintln!("note: {note}");
    }
    if let Some(scale) = depth_scale {
        if !(scale.is_finite() && scale > 0.0) {
            return Err(format!("--depth-scale {scale}: must be a positive number"));
        }
        dataset.depth_scale = Some(scale);
    }
    Ok(dataset)
}

/// Runs `vofront odometry`; the exit code: 0, [`EXIT_LOST`], [`EXIT_SIGINT`] or
/// [`EXIT_SIGTERM`].
pub fn run(args: &OdometryArgs) -> Result<u8, String> {
    let dataset = open_dataset(&args.dataset, &args.input)?;
    let given = args.input.given_camera()?;
    let session = Session::new(dataset, args.method, given).map_err(|e| e.to_string())?;
    let options = TrackerOptions {
        features: args.features,
    };
    let mut tracker = session.tracker(&options).map_err(|e| e.to_string())?;
    let mcap_out = args
        .out
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("mcap"));
    let trajectory = match args.out_format {
        _ if mcap_out => (None, None),
        OutFormat::Tum => (Some(TumSink::new(create_output(&args.out)?)), None),
        OutFormat::Kitti => {
            let times = create_output(&kitti_times_path(&args.out))?;
            (None, Some(KittiSink::new(create_output(&args.out)?, times)))
        }
    };
    let metrics = MetricsCsvSink::new(create_output(&args.metrics)?)
        .map_err(|e| format!("{}: cannot write: {e}", args.metrics.display()))?;
    let graph = args
        .graph
        .as_deref()
        .map(create_output)
        .transpose()?
        .map(G2oSink::new);
    if let Some(path) = &args.plot {
        create_output(path)?;
        std::fs::remove_file(path).map_err(|e| format!("{}: {e}", path.display()))?;
    }
    if let Some(path) = &args.rerun {
        if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
            std::fs::create_dir_all(parent)
                .map_err(|e| format!("{}: cannot write: {e}", path.display()))?;
        }
    }
    let mut viewer = rerun_sink(args, &session)?;
    if !args.json {
        outln!(
            "camera: {} ({})",
            describe_camera(&session.camera),
            session.camera_origin
        );
    }
    let (stop, signal_code) = install_signal_handlers()?;
    let control = RunControl {
        max_frames: args.max_frames,
        stop: Some(&stop),
    };
    let total = args
        .max_frames
        .map_or(session.dataset.len(), |m| m.min(session.dataset.len()));
    let bar = progress_bar(total);
    let progress = |r: &FrameRecord| {
        if let Some(bar) = &bar {
            bar.set_position(r.index as u64 + 1);
        }
        Ok(())
    };
    let pose_bag = mcap_out
        .then(|| create_output(&args.out))
        .transpose()?
        .map(PoseBagSink::new)
        .transpose()
        .map_err(|e| format!("{}: cannot write: {e}", args.out.display()))?;
    let mut sink = (trajectory, (metrics, (graph, (pose_bag, progress))));
    let out = match viewer.as_mut() {
        Some(viewer) => session.run_observed(tracker.as_mut(), &control, &mut sink, viewer),
        None => session.run(tracker.as_mut(), &control, &mut sink),
    };
    if let Some(bar) = &bar {
        bar.finish_and_clear();
    }
    let (_, (_, (_, (pose_bag, _)))) = sink;
    if let Some(bag) = pose_bag {
        bag.finish()
            .map_err(|e| format!("{}: cannot write: {e}", args.out.display()))?;
    }
    if let Some(viewer) = viewer {
        viewer
            .finish()
            .map_err(|e| format!("Rerun recording: {e}"))?;
    }
    let out = out.map_err(|e| e.to_string())?;
    if args.json {
        let report = report_json(args, &session, &out)?;
        outln!(
            "{}",
            serde_json::to_value(&report).map_err(|e| e.to_string())?
        );
    } else {
        report(&session, &out, args.plot.as_deref())?;
    }
    if out.summary.interrupted {
        eprintln!(
            "vofront: interrupted after {} frames; every finished frame is in {} and {}",
            out.summary.frames,
            args.out.display(),
            args.metrics.display()
        );
        return Ok(u8::try_from(signal_code.load(Ordering::SeqCst)).unwrap_or(EXIT_SIGTERM));
    }
    if RunSummary::lost_for_good(&out.records) {
        eprintln!("vofront: tracking was lost for good; partial results written");
        return Ok(EXIT_LOST);
    }
    Ok(0)
}
