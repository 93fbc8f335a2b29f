//! Two views: `relpose` from given correspondences and `two_view` on an image pair.

use std::time::Instant;

use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use vofront::geometry::{estimate_relative_pose, RelativePoseConfig};
use vofront::report::two_view::{model_name, to_json};
use vofront::timing::ms_since;
use vofront::two_view::stereo::StereoFirst;
use vofront::two_view::{estimate, Inputs, Method, UnknownMethod};

use crate::convert::{bad, camera, depth, gray8, json_to_py, points, pose_matrix};
use crate::direct::rotation_translation;
use crate::errors::{failed, release};

/// Robust relative pose `T_21` (`x2 = R x1 + t`, unit `t`) from pixel correspondences
/// `x1[i] <-> x2[i]` ((N, 2) arrays, pixels through the lens model of `K`, `dist`): essential
/// and homography RANSAC with model selection, chirality and refinement.
///
/// Returns the keys of `vofront relpose` (`R`, `t`, `inliers`, `ms`) and `T_21` (4x4),
/// `model` (`essential` / `homography`), `parallax_deg`, `inlier_mask` (N,) bool and
/// `quality` (the record of `vofront relpose --json`: `verdict`, `reasons`, support, `sigma`,
/// covariances, `rotation_sigma_deg`, `translation_direction_sigma_deg`).
#[pyfunction]
#[pyo3(signature = (x1, x2, K, dist = None))]
#[allow(non_snake_case)]
pub fn relpose<'py>(
    py: Python<'py>,
    x1: &Bound<'py, PyAny>,
    x2: &Bound<'py, PyAny>,
    K: &Bound<'py, PyAny>,
    dist: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let (x1, x2) = (points(x1, "x1")?, points(x2, "x2")?);
    if x1.len() != x2.len() {
        return Err(bad(format!(
            "x1 and x2 must have the same length, got {} and {}",
            x1.len(),
            x2.len()
        )));
    }
    let camera = camera(K, dist)?;
    let (fit, ms) = release(py, || {
        let start = Instant::now();
        let fit = estimate_relative_pose(&x1, &x2, &camera, &RelativePoseConfig::default())
            .map_err(failed)?;
        Ok((fit, ms_since(start)))
    })?;
    let out = PyDict::new(py);
    let (r, _) = rotation_translation(py, &fit.pose)?;
    let t = fit.translation();
    out.set_item("R", r)?;
    out.set_item("t", PyArray1::from_slice(py, &[t.x, t.y, t.z]))?;
    out.set_item("inliers", fit.inlier_count())?;
    out.set_item("ms", ms)?;
    out.set_item("T_21", pose_matrix(py, &fit.pose))?;
    out.set_item("model", model_name(fit.model))?;
    out.set_item("parallax_deg", fit.parallax_deg)?;
    out.set_item("inlier_mask", PyArray1::from_slice(py, &fit.inliers))?;
    let quality = serde_json::to_value(&fit.quality).map_err(|e| bad(e.to_string()))?;
    out.set_item("quality", json_to_py(py, &quality)?)?;
    Ok(out)
}

/// Feature pose, direct 2D shift and (with `depth1`) direct SE(3) pose of one pair, computed
/// and reported by the library exactly as `vofront two-view --json` does (same keys; a failed
/// method gives `{"error": message}`), each pose also as a 4x4 `T_21` array. With `right1`
/// (frame 1's rectified right image) and `baseline` (metres) the metric `feature_stereo` pose
/// is added, and without `depth1` the direct SE(3) pose uses frame 1's stereo depth.
#[pyfunction]
#[pyo3(signature = (img1, img2, K, dist = None, method = "all", depth1 = None, depth_scale = 5000.0, features = 2000, right1 = None, baseline = None))]
#[allow(non_snake_case)]
#[allow(clippy::too_many_arguments)]
pub fn two_view<'py>(
    py: Python<'py>,
    img1: &Bound<'py, PyAny>,
    img2: &Bound<'py, PyAny>,
    K: &Bound<'py, PyAny>,
    dist: Option<&Bound<'py, PyAny>>,
    method: &str,
    depth1: Option<&Bound<'py, PyAny>>,
    depth_scale: f64,
    features: usize,
    right1: Option<&Bound<'py, PyAny>>,
    baseline: Option<f64>,
) -> PyResult<Bound<'py, PyDict>> {
    let method: Method = method
        .parse()
        .map_err(|e: UnknownMethod| bad(e.to_string()))?;
    let depth1 = match depth1.filter(|d| !d.is_none()) {
        Some(d) => Some(depth(d, depth_scale, "depth1")?),
        None => None,
    };
    let stereo = match (right1.filter(|r| !r.is_none()), baseline) {
        (Some(r), Some(baseline)) => Some(StereoFirst {
            right1: gray8(r, "right1")?,
            baseline,
        }),
        (None, None) => None,
        _ => return Err(bad("right1 and baseline go together")),
    };
    let inputs = Inputs {
        img1: gray8(img1, "img1")?,
        img2: gray8(img2, "img2")?,
        depth1,
        camera: camera(K, dist)?,
        method,
        features,
        stereo,
    };
    let (report, poses) = release(py, || {
        let outcome = estimate(&inputs);
        let poses = [
            (
                "feature",
                outcome
                    .feature
                    .as_ref()
                    .and_then(|r| r.as_ref().ok())
                    .map(|f| f.estimate.pose),
            ),
            (
                "feature_stereo",
                outcome
                    .feature_stereo
                    .as_ref()
                    .and_then(|r| r.as_ref().ok())
                    .map(|s| s.pnp.pose),
            ),
            (
                "direct_se3",
                outcome
                    .se3
                    .as_ref()
                    .and_then(|r| r.as_ref().ok())
                    .map(|s| s.0.pose),
            ),
        ];
        Ok((to_json(&outcome), poses))
    })?;
    let dict = json_to_py(py, &report)?.downcast_into::<PyDict>()?;
    for (key, pose) in poses {
        if let (Some(entry), Some(pose)) = (dict.get_item(key)?, pose) {
            entry.set_item("T_21", pose_matrix(py, &pose))?;
        }
    }
    Ok(dict)
}
