//! Trajectory evaluation: `ate` and `rpe`, as `vofront eval` (and evo) compute them.

use std::path::PathBuf;

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};
use numpy::{AllowTypeChange, PyArray1, PyArrayLike2};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use vofront::eval::{ate as ate_of, rpe as rpe_of, Alignment, EvalConfig, Stats};
use vofront::trajectory::{
    kitti_pose, pair_untimed, Trajectory, TrajectoryError, TrajectoryFile, TrajectoryFormat,
};

use crate::convert::bad;
use crate::errors::{failed, release, trajectory_error};

/// `t tx ty tz qx qy qz qw` per pose, row-major.
pub fn tum_rows(t: &Trajectory) -> Vec<f64> {
    t.poses
        .iter()
        .flat_map(|(stamp, p)| {
            let (v, q) = (p.translation.vector, p.rotation.coords);
            [*stamp, v.x, v.y, v.z, q.x, q.y, q.z, q.w]
        })
        .collect()
}

/// A trajectory from a file path (TUM, KITTI or EuRoC: `format`, else detected; `times`
/// stamps a KITTI file), an (N, 8) array of TUM rows or an (N, 12) array of KITTI rows.
fn trajectory(
    obj: &Bound<'_, PyAny>,
    what: &str,
    format: Option<TrajectoryFormat>,
    times: Option<PathBuf>,
) -> PyResult<TrajectoryFile> {
    if let Ok(path) = obj.extract::<PathBuf>() {
        return TrajectoryFile::read(&path, format, times.as_deref()).map_err(|e| match e {
            TrajectoryError::TimesNotKitti { .. } => bad(format!("{what}: {e}")),
            e => trajectory_error(e),
        });
    }
    let a: PyArrayLike2<'_, f64, AllowTypeChange> = obj.extract().map_err(|_| {
        bad(format!(
            "{what}: expected a trajectory file path, an (N, 8) array of TUM rows t tx ty tz qx \
             qy qz qw or an (N, 12) array of KITTI rows"
        ))
    })?;
    if times.is_some() {
        return Err(bad(format!(
            "{what}: times are for KITTI files, not arrays"
        )));
    }
    let a = a.as_array();
    let kitti = match a.ncols() {
        8 => false,
        12 => true,
        _ => {
            return Err(bad(format!(
                "{what}: expected shape (N, 8) or (N, 12), got {:?}",
                a.shape()
            )))
        }
    };
    let mut poses = Vec::with_capacity(a.nrows());
    for (i, r) in a.rows().into_iter().enumerate() {
        let pose = if kitti {
            kitti_pose(&r.to_vec()).ok()
        } else {
            tum_row(&r.to_vec())
        };
        let pose = pose.ok_or_else(|| {
            bad(format!(
                "{what}: row {i} is not finite or has no rotation (zero quaternion or a 3x3 \
                 block that is not a rotation)"
            ))
        })?;
        poses.push((if kitti { i as f64 } else { r[0] }, pose));
    }
    Ok(TrajectoryFile {
        trajectory: Trajectory::new(poses),
        format: if kitti {
            TrajectoryFormat::Kitti
        } else {
            TrajectoryFormat::Tum
        },
        timed: !kitti,
    })
}

/// The pose of a TUM row `t tx ty tz qx qy qz qw`; `None` when not finite or zero quaternion.
fn tum_row(r: &[f64]) -> Option<Isometry3<f64>> {
    let q = Quaternion::new(r[7], r[4], r[5], r[6]);
    (r.iter().all(|v| v.is_finite()) && q.norm() >= 1e-9).then(|| {
        Isometry3::from_parts(
            Translation3::new(r[1], r[2], r[3]),
            UnitQuaternion::from_quaternion(q),
        )
    })
}

/// The two trajectories of `ate` / `rpe`, matched by index when one has no timestamps.
fn pair(
    gt: &Bound<'_, PyAny>,
    est: &Bound<'_, PyAny>,
    format: Option<&str>,
    gt_times: Option<PathBuf>,
    est_times: Option<PathBuf>,
) -> PyResult<(Trajectory, Trajectory)> {
    let format = format
        .map(|f| f.parse::<TrajectoryFormat>().map_err(bad))
        .transpose()?;
    let gt = trajectory(gt, "gt", format, gt_times)?;
    let est = trajectory(est, "est", format, est_times)?;
    pair_untimed(gt, est).map_err(|e| bad(e.to_string()))
}

fn alignment(name: Option<&str>) -> PyResult<Alignment> {
    match name {
        None | Some("none") => Ok(Alignment::None),
        Some("se3") => Ok(Alignment::Se3),
        Some("sim3") => Ok(Alignment::Sim3),
        Some(other) => Err(bad(format!(
            "align must be 'se3', 'sim3' or 'none', got '{other}'"
        ))),
    }
}

/// Summary statistics as `vofront eval --json` prints them (plus `sse`).
pub fn stats_dict<'py>(py: Python<'py>, s: &Stats) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    for (k, v) in [
        ("rmse", s.rmse),
        ("mean", s.mean),
        ("median", s.median),
        ("std", s.std),
        ("min", s.min),
        ("max", s.max),
        ("sse", s.sse),
    ] {
        d.set_item(k, v)?;
    }
    d.set_item("count", s.count)?;
    Ok(d)
}

/// Absolute trajectory error (translation, metres) of `est` against `gt`, as
/// `evo_ape tum gt est [--align [--correct_scale]]`.
///
/// `gt`, `est`: trajectory files, TUM, KITTI or EuRoC CSV (`format`: `tum`, `kitti` or
/// `euroc` for both, else detected from each file's content, as `vofront eval`), (N, 8)
/// arrays of TUM rows `t tx ty tz qx qy qz qw` or (N, 12) arrays of KITTI rows (camera-to-world).
/// `gt_times`, `est_times`: KITTI `times.txt` files stamping KITTI poses; a KITTI trajectory
/// without times is matched to the other by index (both need as many poses).
/// `align`: `se3` (rigid Umeyama, default as in `vofront eval`), `sim3` (with scale) or
/// `none`; `max_dt`: largest timestamp difference for associating poses, seconds.
/// Returns the statistics (`rmse`, `mean`, `median`, `std`, `min`, `max`, `sse`, `count`)
/// with `pairs`, `alignment`, `scale` and `errors` (per associated pose, metres).
#[pyfunction]
#[pyo3(signature = (gt, est, align = Some("se3"), max_dt = 0.01, format = None, gt_times = None, est_times = None))]
#[pyo3(
    text_signature = "(gt, est, align=\"se3\", max_dt=0.01, format=None, gt_times=None, est_times=None)"
)]
#[allow(clippy::too_many_arguments)] // the Python keyword arguments
pub fn ate<'py>(
    py: Python<'py>,
    gt: &Bound<'py, PyAny>,
    est: &Bound<'py, PyAny>,
    align: Option<&str>,
    max_dt: f64,
    format: Option<&str>,
    gt_times: Option<PathBuf>,
    est_times: Option<PathBuf>,
) -> PyResult<Bound<'py, PyDict>> {
    let (gt, est) = pair(gt, est, format, gt_times, est_times)?;
    let alignment = alignment(align)?;
    let cfg = EvalConfig { max_dt, alignment };
    let a = release(py, || {
        ate_of(&gt, &est, &cfg).map_err(|e| failed(format!("ATE: {e}")))
    })?;
    let d = stats_dict(py, &a.stats)?;
    d.set_item("pairs", a.pairs.len())?;
    d.set_item("alignment", align.unwrap_or("none"))?;
    d.set_item("scale", a.alignment.scale)?;
    let errors: Vec<f64> = a.errors.iter().map(|e| e.1).collect();
    d.set_item("errors", PyArray1::from_vec(py, errors))?;
    Ok(d)
}

/// Relative pose error over consecutive associated poses, as
/// `evo_rpe tum gt est --delta 1 --delta_unit f`: a dict with `translation` (metres) and
/// `rotation_deg` statistics, `rotation_scale` (`{"scale", "sigma"}`: the least-squares factor
/// of the estimated over the true relative rotations and its standard deviation, `None` when
/// the ground truth does not rotate) and `pairs`. A rigid alignment leaves relative poses
/// unchanged, so only `align="sim3"` (scale) changes the result, as in `vofront eval`.
#[pyfunction]
#[pyo3(signature = (gt, est, align = Some("se3"), max_dt = 0.01, format = None, gt_times = None, est_times = None))]
#[pyo3(
    text_signature = "(gt, est, align=\"se3\", max_dt=0.01, format=None, gt_times=None, est_times=None)"
)]
#[allow(clippy::too_many_arguments)] // the Python keyword arguments
pub fn rpe<'py>(
    py: Python<'py>,
    gt: &Bound<'py, PyAny>,
    est: &Bound<'py, PyAny>,
    align: Option<&str>,
    max_dt: f64,
    format: Option<&str>,
    gt_times: Option<PathBuf>,
    est_times: Option<PathBuf>,
) -> PyResult<Bound<'py, PyDict>> {
    let (gt, est) = pair(gt, est, format, gt_times, est_times)?;
    let alignment = match alignment(align)? {
        Alignment::Sim3 => Alignment::Sim3,
        _ => Alignment::None,
    };
    let cfg = EvalConfig { max_dt, alignment };
    let r = release(py, || {
        rpe_of(&gt, &est, &cfg).map_err(|e| failed(format!("RPE: {e}")))
    })?;
    let d = PyDict::new(py);
    d.set_item("translation", stats_dict(py, &r.translation)?)?;
    d.set_item("rotation_deg", stats_dict(py, &r.rotation_deg)?)?;
    let turn = match r.rotation_scale {
        Some(k) => {
            let t = PyDict::new(py);
            t.set_item("scale", k.scale)?;
            t.set_item("sigma", k.sigma)?;
            Some(t)
        }
        None => None,
    };
    d.set_item("rotation_scale", turn)?;
    d.set_item("pairs", r.pairs.len())?;
    Ok(d)
}
