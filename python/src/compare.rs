//! `compare`: every tracker a dataset allows, run on the same frames and scored side by side.

use std::path::PathBuf;

use pyo3::exceptions::PyOSError;
use pyo3::prelude::*;
use vofront::compare::{compare as run_compare, write_report, CompareConfig};
use vofront::dataset::Dataset;
use vofront::odometry::run::RunControl;

use crate::convert::{bad, camera, json_to_py};
use crate::errors::{dataset_error, release};
use crate::odometry::tracker_kind;

/// Runs every tracker the dataset at `dataset_path` allows (the RGB-D ones with depth, the
/// stereo ones with a stereo rig, the monocular ones always), or the `methods` named, on the
/// same frames, as `vofront compare` does, and returns its report as a dict (the keys of
/// `vofront compare --json`: `dataset`, `format`, `frames`, `camera`, `ground_truth`,
/// `trackers` (per tracker `method`, `paradigm`, `alignment`, `error`, counts, `lost_spans`,
/// `ms_mean`, `ms_median`, `ate`, `ate_percent`, `rpe`, `series`), `skipped`, `wall_ms`,
/// `interrupted`). `K`, `dist`: the camera of the monocular and RGB-D trackers (the dataset's
/// when None); `out_dir`: also write `report.json` and `report.html` there.
#[pyfunction]
#[pyo3(signature = (dataset_path, methods = None, K = None, dist = None, max_frames = None, out_dir = None))]
#[allow(non_snake_case)]
pub fn compare<'py>(
    py: Python<'py>,
    dataset_path: PathBuf,
    methods: Option<Vec<String>>,
    K: Option<&Bound<'py, PyAny>>,
    dist: Option<&Bound<'py, PyAny>>,
    max_frames: Option<usize>,
    out_dir: Option<PathBuf>,
) -> PyResult<Bound<'py, PyAny>> {
    let methods = methods
        .map(|names| {
            names
                .iter()
                .map(|n| tracker_kind(n))
                .collect::<PyResult<Vec<_>>>()
        })
        .transpose()?;
    let camera = match K.filter(|k| !k.is_none()) {
        Some(k) => Some((camera(k, dist)?, "K argument".to_string())),
        None => None,
    };
    let config = CompareConfig {
        methods,
        camera,
        max_frames,
        ..CompareConfig::default()
    };
    let dataset = release(py, || Dataset::open(&dataset_path).map_err(dataset_error))?;
    let report = release(py, || {
        let report = run_compare(&dataset, &config, &RunControl::default());
        if let Some(dir) = &out_dir {
            write_report(dir, &report).map_err(|e| PyOSError::new_err(e.to_string()))?;
        }
        Ok(report)
    })?;
    let value = serde_json::to_value(&report).map_err(|e| bad(e.to_string()))?;
    json_to_py(py, &value)
}
