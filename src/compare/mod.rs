//! Every tracker the dataset allows, run on the same frames and scored side by side
//! (`vofront compare DATASET`, Python `vofront.compare`).
//!
//! The trackers come from the registry: [`TrackerKind::ALL`] filtered by
//! [`TrackerKind::check`] (depth for the RGB-D trackers, a stereo rig for the stereo ones,
//! every dataset for the monocular ones), so a tracker added to the registry appears here
//! without a change. Each runs through [`crate::odometry::registry::Session`] with the same
//! camera, options and frame limit ([`CompareConfig`]); its trajectory is scored against the
//! camera ground truth with its own alignment ([`TrackerKind::alignment`]: Sim(3) where the
//! scale is arbitrary, SE(3) for metric trackers). A tracker that cannot run (a kind asked
//! for by name on a dataset without what it needs) is listed with its typed error.
//!
//! - [`tracker`]: one tracker's run and scores ([`TrackerResult`]: ATE, RPE, frames tracked,
//!   posed and lost, segment breaks, where it lost track, time per frame, per-frame series);
//! - [`table`]: the text table;
//! - [`figures`]: the pictures as SVG (trajectories over the ground truth, per-frame error,
//!   inliers beside the photometric residual);
//! - [`html`]: the self-contained `report.html` ([`write_report`] writes it with
//!   `report.json`).
//!
//! ```
//! use vofront::compare::{compare, CompareConfig};
//! use vofront::dataset::Dataset;
//! use vofront::odometry::run::RunControl;
//! use vofront_fixtures::scene::{default_camera, rescaled_camera, room_trajectory, Scene};
//! use vofront_fixtures::tum::write_tum_sequence;
//!
//! let dir = std::env::temp_dir().join(format!("vofront-doc-compare-{}", std::process::id()));
//! let camera = rescaled_camera(&default_camera(), 0.5);
//! write_tum_sequence(&dir, &Scene::box_room(2), &camera, (320, 240), &room_trajectory(6)).unwrap();
//! let dataset = Dataset::open(&dir).unwrap();
//! let config = CompareConfig {
//!     camera: Some((camera, "the rendering camera".into())),
//!     ..CompareConfig::default()
//! };
//! let report = compare(&dataset, &config, &RunControl::default());
//! // A TUM RGB-D folder: the RGB-D and the monocular trackers; the stereo ones are skipped.
//! let names: Vec<&str> = report.trackers.iter().map(|t| t.method.name()).collect();
//! assert!(names.contains(&"direct") && names.contains(&"mono"));
//! assert!(report.skipped.iter().any(|s| s.method == "stereo"));
//! let direct = report.trackers.iter().find(|t| t.method.name() == "direct").unwrap();
//! assert_eq!(direct.run.as_ref().unwrap().posed, 6);
//! std::fs::remove_dir_all(&dir).unwrap();
//! ```

pub mod figures;
pub mod html;
pub mod table;
pub mod tracker;

use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::Serialize;
use thiserror::Error;
use vofront_core::Camera;

pub use tracker::{run_tracker, FramePoint, TrackerResult, TrackerRun};

use crate::dataset::Dataset;
use crate::odometry::registry::{choose_camera, TrackerKind, TrackerOptions};
use crate::odometry::run::RunControl;
use crate::report::odometry::CameraReport;
use crate::timing::ms_since;
use crate::trajectory::Trajectory;

/// What every tracker of a comparison shares.
#[derive(Debug, Clone, Default)]
pub struct CompareConfig {
    /// The trackers to run, in this order; `None`: every tracker the dataset allows
    /// ([`plan`]).
    pub methods: Option<Vec<TrackerKind>>,
    /// A camera given by the caller and how it was given (e.g. `command-line flags`); `None`:
    /// the dataset's, else `tum-ros` ([`choose_camera`]).
    pub camera: Option<(Camera, String)>,
    /// Options applied to every tracker (the ORB budget of the feature trackers).
    pub options: TrackerOptions,
    /// Track only the first `n` frames.
    pub max_frames: Option<usize>,
}

/// A tracker left out of a comparison because the dataset lacks what it needs.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Skipped {
    /// The tracker's name.
    pub method: &'static str,
    /// Why ([`TrackerKind::check`]'s error).
    pub reason: String,
}

/// Which trackers a comparison runs on `dataset`, and which it leaves out: `methods` as given
/// (every one runs, a missing need is its error), or every kind of [`TrackerKind::ALL`] whose
/// needs the dataset meets ([`TrackerKind::check`]).
pub fn plan(
    dataset: &Dataset,
    methods: Option<&[TrackerKind]>,
) -> (Vec<TrackerKind>, Vec<Skipped>) {
    if let Some(methods) = methods {
        let mut run: Vec<TrackerKind> = Vec::new();
        for kind in methods {
            if !run.contains(kind) {
                run.push(*kind);
            }
        }
        return (run, Vec::new());
    }
    let mut run = Vec::new();
    let mut skipped = Vec::new();
    for kind in TrackerKind::ALL {
        match kind.check(dataset) {
            Ok(()) => run.push(*kind),
            Err(e) => skipped.push(Skipped {
                method: kind.name(),
                reason: e.to_string(),
            }),
        }
    }
    (run, skipped)
}

/// The comparison: every tracker's result on one dataset (`vofront compare --json`, keys in
/// the README).
#[derive(Debug, Serialize)]
pub struct CompareReport {
    /// The folder (or bag) that was opened.
    pub dataset: String,
    /// Its format, lower case (`tum`, `kitti`, `euroc`, `images`, ...).
    pub format: String,
    /// Frames each tracker was given (the dataset's, or the frame limit).
    pub frames: usize,
    /// The camera of the monocular and RGB-D trackers (the stereo ones use the dataset's rig).
    pub camera: CameraReport,
    /// The dataset has ground truth.
    pub ground_truth: bool,
    /// The trackers run, in order.
    pub trackers: Vec<TrackerResult>,
    /// The trackers the dataset does not allow.
    pub skipped: Vec<Skipped>,
    /// Wall time of the whole comparison so far, milliseconds.
    pub wall_ms: f64,
    /// The comparison was stopped before every tracker had run to the end.
    pub interrupted: bool,
    /// The camera ground truth `T_wc` (for the figures; not in the JSON).
    #[serde(skip)]
    pub ground_truth_trajectory: Option<Trajectory>,
}

impl CompareReport {
    /// One line on what was compared: dataset (format), frames, the camera's source, and
    /// whether the ground truth is missing or the run was interrupted.
    pub fn headline(&self) -> String {
        format!(
            "{} ({}), {} frames, camera: {}{}{}",
            self.dataset,
            self.format,
            self.frames,
            self.camera.source,
            if self.ground_truth {
                ""
            } else {
                ", no ground truth"
            },
            if self.interrupted {
                ", interrupted"
            } else {
                ""
            }
        )
    }

    /// An empty report on `dataset` with `config`'s camera and frame limit, leaving out
    /// `skipped`.
    pub fn new(dataset: &Dataset, config: &CompareConfig, skipped: Vec<Skipped>) -> Self {
        let given = config.camera.as_ref().map(|(c, how)| (*c, how.as_str()));
        let (camera, origin) = choose_camera(given, dataset);
        let ground_truth_trajectory = dataset.camera_ground_truth();
        Self {
            dataset: dataset.root.display().to_string(),
            format: format!("{:?}", dataset.kind).to_lowercase(),
            frames: config
                .max_frames
                .map_or(dataset.len(), |m| m.min(dataset.len())),
            camera: CameraReport::new(&camera, &origin),
            ground_truth: ground_truth_trajectory.is_some(),
            trackers: Vec::new(),
            skipped,
            wall_ms: 0.0,
            interrupted: false,
            ground_truth_trajectory,
        }
    }

    /// The result of a tracker that ran (or failed), counted in.
    pub fn push(&mut self, result: TrackerResult) {
        self.interrupted |= result.run.as_ref().is_some_and(|r| r.interrupted);
        self.trackers.push(result);
    }
}

/// Runs every tracker of [`plan`] on `dataset` in turn (each bounded by `control`: a raised
/// stop flag ends the tracker in progress and skips the rest) and returns the report.
pub fn compare(
    dataset: &Dataset,
    config: &CompareConfig,
    control: &RunControl<'_>,
) -> CompareReport {
    let start = Instant::now();
    let (kinds, skipped) = plan(dataset, config.methods.as_deref());
    let mut report = CompareReport::new(dataset, config, skipped);
    for kind in kinds {
        if report.interrupted {
            break;
        }
        let mut no_sink = |_: &crate::odometry::run::FrameRecord| Ok::<(), std::io::Error>(());
        report.push(run_tracker(dataset, kind, config, control, &mut no_sink));
        report.wall_ms = ms_since(start);
    }
    report
}

/// Errors of [`write_report`].
#[derive(Debug, Error)]
pub enum CompareError {
    /// A file could not be written.
    #[error("{}: cannot write: {source}", path.display())]
    Io {
        /// The file or folder.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// The report could not be serialised.
    #[error("cannot serialise the report: {0}")]
    Json(#[from] serde_json::Error),
}

/// Writes `report.json` (the report's JSON, as `--json` prints it) and `report.html` (the
/// page of [`html::page`], pictures inline) into `dir`, created if needed.
pub fn write_report(dir: &Path, report: &CompareReport) -> Result<(), CompareError> {
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| CompareError::Io { path, source }
    };
    std::fs::create_dir_all(dir).map_err(io(dir))?;
    let json = serde_json::to_string_pretty(report)?;
    let path = dir.join("report.json");
    std::fs::write(&path, json).map_err(io(&path))?;
    let path = dir.join("report.html");
    std::fs::write(&path, html::page(report)).map_err(io(&path))?;
    Ok(())
}
