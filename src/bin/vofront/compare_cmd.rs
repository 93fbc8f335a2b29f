//! `vofront compare DATASET`: every tracker the dataset allows (or `--methods`) on the same
//! frames, one after the other, and the report as a table (or `--json`); with `--out-dir` each
//! tracker's TUM trajectory streamed as it is tracked, and `report.json` and `report.html`
//! rewritten after each tracker, so an interrupted comparison keeps what finished.

use std::sync::atomic::Ordering;
use std::time::Instant;

use vofront::compare::{
    plan, run_tracker, table::table, write_report, CompareConfig, CompareReport,
};
use vofront::odometry::registry::TrackerOptions;
use vofront::odometry::run::{FrameRecord, RunControl, TumSink};
use vofront::timing::ms_since;

use crate::args::CompareArgs;
use crate::odometry_cmd::{
    create_output, install_signal_handlers, open_dataset, progress_bar, EXIT_SIGTERM,
};

/// Runs `vofront compare`; the exit code: 0, 1 when no tracker ran, 130 / 143 when
/// interrupted.
pub fn run(args: &CompareArgs) -> Result<u8, String> {
    let dataset = open_dataset(&args.dataset, &args.input)?;
    let camera = args
        .input
        .given_camera()?
        .map(|(camera, source)| (camera, source.to_string()));
    let config = CompareConfig {
        methods: args.methods.clone(),
        camera,
        options: TrackerOptions {
            features: args.features,
        },
        max_frames: args.max_frames,
    };
    let (kinds, skipped) = plan(&dataset, config.methods.as_deref());
    let mut report = CompareReport::new(&dataset, &config, skipped);
    let write = |report: &CompareReport| match &args.out_dir {
        Some(dir) => write_report(dir, report).map_err(|e| e.to_string()),
        None => Ok(()),
    };
    write(&report)?;
    let (stop, signal_code) = install_signal_handlers()?;
    let control = RunControl {
        max_frames: None,
        stop: Some(&stop),
    };
    let start = Instant::now();
    for kind in kinds {
        if report.interrupted || stop.load(Ordering::SeqCst) {
            report.interrupted = true;
            break;
        }
        let tum = match (&args.out_dir, kind.check(&dataset)) {
            (Some(dir), Ok(())) => Some(TumSink::new(create_output(
                &dir.join(format!("{}.txt", kind.name())),
            )?)),
            _ => None,
        };
        let bar = progress_bar(report.frames);
        let progress = |r: &FrameRecord| {
            if let Some(bar) = &bar {
                bar.set_position(r.index as u64 + 1);
            }
            Ok(())
        };
        let mut sink = (tum, progress);
        let result = run_tracker(&dataset, kind, &config, &control, &mut sink);
        drop(sink);
        if let Some(bar) = bar {
            bar.finish_and_clear();
        }
        report.push(result);
        report.wall_ms = ms_since(start);
        write(&report)?;
    }
    if args.json {
        outln!(
            "{}",
            serde_json::to_string(&report).map_err(|e| e.to_string())?
        );
    } else {
        out!("{}", table(&report));
        if let Some(dir) = &args.out_dir {
            outln!("report: {}", dir.join("report.html").display());
        }
    }
    if report.interrupted {
        eprintln!("vofront: interrupted; every finished tracker is in the report");
        return Ok(u8::try_from(signal_code.load(Ordering::SeqCst))
            .ok()
            .filter(|c| *c != 0)
            .unwrap_or(EXIT_SIGTERM));
    }
    if report.trackers.iter().all(|t| t.run.is_none()) {
        eprintln!("vofront: no tracker ran on this dataset");
        return Ok(1);
    }
    Ok(0)
}
