//! Two views: `relpose` from given correspondences and `two_view` on an image pair.

use std::time::Instant;

use nalgebra::{Isometry3, Matrix3};
use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use serde_json::{json, Value};
use vofront::direct::{align_se3, align_translation, RgbdFrame, Se3Config, TranslationConfig};
use vofront::geometry::{estimate_relative_pose, Camera, Model, RelativePoseConfig};
use vofront::input::DepthMap;
use vofront::pipeline::{depth_plane, FeatureTracker};

use crate::convert::{bad, camera, depth, image, json_to_py, points, pose_matrix, Image};
use crate::direct::{ms_since, rotation_translation};
use crate::errors::{failed, release};

/// Robust relative pose `T_21` (`x2 = R x1 + t`, unit `t`) from pixel correspondences
/// `x1[i] <-> x2[i]` ((N, 2) arrays, pixels through the lens model of `K`, `dist`): essential
/// and homography RANSAC with model selection, chirality and refinement.
///
/// Returns the keys of `vofront relpose` (`R`, `t`, `inliers`, `ms`) and `T_21` (4x4),
/// `model` (`essential` / `homography`), `parallax_deg`, `inlier_mask` (N,) bool.
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
    let t = fit.translation;
    out.set_item("R", r)?;
    out.set_item("t", PyArray1::from_slice(py, &[t.x, t.y, t.z]))?;
    out.set_item("inliers", fit.inlier_count)?;
    out.set_item("ms", ms)?;
    out.set_item("T_21", pose_matrix(py, &fit.pose))?;
    let model = match fit.model {
        Model::Essential => "essential",
        Model::Homography => "homography",
    };
    out.set_item("model", model)?;
    out.set_item("parallax_deg", fit.parallax_deg)?;
    out.set_item("inlier_mask", PyArray1::from_slice(py, &fit.inliers))?;
    Ok(out)
}

/// Which estimators `two_view` runs (`vofront two-view --method`).
fn parse_method(method: &str) -> PyResult<(bool, bool)> {
    match method {
        "all" => Ok((true, true)),
        "feature" => Ok((true, false)),
        "direct" => Ok((false, true)),
        _ => Err(bad(format!(
            "method must be 'feature', 'direct' or 'all', got '{method}'"
        ))),
    }
}

fn rows(m: &Matrix3<f64>) -> Value {
    json!([
        [m[(0, 0)], m[(0, 1)], m[(0, 2)]],
        [m[(1, 0)], m[(1, 1)], m[(1, 2)]],
        [m[(2, 0)], m[(2, 1)], m[(2, 2)]]
    ])
}

fn check_same_size(a: (usize, usize), b: (usize, usize), what: &str) -> Result<(), String> {
    if a == b {
        Ok(())
    } else {
        Err(format!(
            "image size {}x{} differs from {what} size {}x{}",
            a.0, a.1, b.0, b.1
        ))
    }
}

fn or_error<T>(r: Result<T, String>, f: impl FnOnce(T) -> Value) -> Value {
    r.map_or_else(|e| json!({ "error": e }), f)
}

/// The two-view estimates as the CLI's JSON object (keys `feature`, `direct_translation`,
/// `direct_se3`), each with its pose `T_21` on the side.
struct TwoView {
    json: serde_json::Map<String, Value>,
    poses: Vec<(&'static str, Isometry3<f64>)>,
}

fn estimate_two_view(
    img1: &Image,
    img2: &Image,
    depth1: Option<&DepthMap>,
    camera: &Camera,
    (run_feature, run_direct): (bool, bool),
    features: usize,
) -> TwoView {
    let mut out = TwoView {
        json: serde_json::Map::new(),
        poses: Vec::new(),
    };
    if run_feature {
        let fit = FeatureTracker::with_features(features)
            .relative_pose(&img1.gray8(), &img2.gray8(), camera)
            .map_err(|e| e.to_string());
        if let Ok(f) = &fit {
            out.poses.push(("feature", f.estimate.pose));
        }
        out.json.insert("feature".into(), or_error(fit, |f| {
            let e = &f.estimate;
            let t = e.translation;
            json!({
                "R": rows(&e.pose.rotation.to_rotation_matrix().into_inner()),
                "t": [t.x, t.y, t.z],
                "keypoints": [f.features[0].len(), f.features[1].len()],
                "matches": f.matches.len(),
                "inliers": e.inlier_count,
                "model": match e.model { Model::Essential => "essential", Model::Homography => "homography" },
                "parallax_deg": e.parallax_deg,
                "ms": {"detect": f.timings.detect, "match": f.timings.matching,
                       "estimate": f.timings.estimate, "total": f.timings.total},
            })
        }));
    }
    if !run_direct {
        return out;
    }
    let shift = check_same_size(img1.size(), img2.size(), "frame 2").and_then(|()| {
        let start = Instant::now();
        let fit = align_translation(&img1.plane(), &img2.plane(), &TranslationConfig::default())
            .map_err(|e| e.to_string())?;
        Ok((fit, ms_since(start)))
    });
    out.json.insert("direct_translation".into(), or_error(shift, |(d, ms)| {
        json!({"d": [d.d.x, d.d.y], "iterations": d.iterations.iter().sum::<usize>(), "rmse": d.rmse, "ms": ms})
    }));
    let Some(depth) = depth1 else {
        return out;
    };
    let se3 = check_same_size(img1.size(), img2.size(), "frame 2")
        .and_then(|()| {
            let d = depth.dimensions();
            check_same_size(img1.size(), (d.0 as usize, d.1 as usize), "depth")
        })
        .and_then(|()| {
            let current = img2.plane();
            let start = Instant::now();
            let reference = RgbdFrame::new(img1.plane().into_owned(), depth_plane(depth), camera)
                .map_err(|e| e.to_string())?;
            let fit = align_se3(
                &reference,
                &current,
                &Isometry3::identity(),
                &Se3Config::default(),
            )
            .map_err(|e| e.to_string())?;
            Ok((fit, ms_since(start)))
        });
    if let Ok((s, _)) = &se3 {
        out.poses.push(("direct_se3", s.pose));
    }
    out.json.insert("direct_se3".into(), or_error(se3, |(s, ms)| {
        let t = s.pose.translation.vector;
        json!({"R": rows(&s.pose.rotation.to_rotation_matrix().into_inner()), "t": [t.x, t.y, t.z],
               "a": s.a, "b": s.b, "inlier_ratio": s.inlier_ratio, "rmse": s.rmse, "ms": ms})
    }));
    out
}

/// Feature pose, direct 2D shift and (with `depth1`) direct SE(3) pose of one pair, as
/// `vofront two-view --json` computes them (same keys; a failed method gives
/// `{"error": message}`), each pose also as a 4x4 `T_21` array.
#[pyfunction]
#[pyo3(signature = (img1, img2, K, dist = None, method = "all", depth1 = None, depth_scale = 5000.0, features = 2000))]
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
) -> PyResult<Bound<'py, PyDict>> {
    let which = parse_method(method)?;
    let (img1, img2) = (image(img1, "img1")?, image(img2, "img2")?);
    let depth1 = match depth1.filter(|d| !d.is_none()) {
        Some(d) => Some(depth(d, depth_scale, "depth1")?),
        None => None,
    };
    let camera = camera(K, dist)?;
    let out = release(py, || {
        Ok(estimate_two_view(
            &img1,
            &img2,
            depth1.as_ref(),
            &camera,
            which,
            features,
        ))
    })?;
    let dict = json_to_py(py, &Value::Object(out.json))?.downcast_into::<PyDict>()?;
    for (key, pose) in &out.poses {
        if let Some(entry) = dict.get_item(key)? {
            entry.set_item("T_21", pose_matrix(py, pose))?;
        }
    }
    Ok(dict)
}
