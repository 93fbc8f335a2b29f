//! Direct methods: 2D translation, SE(3) photometric alignment, KLT tracking.

use std::time::Instant;

use nalgebra::{Isometry3, Vector2};
use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use vofront::direct::{
    align_se3 as se3, align_translation as translation, track_klt, KltConfig, KltStatus, RgbdFrame,
    Se3Config, TranslationConfig,
};
use vofront::timing::ms_since;

use crate::convert::{array2, bad, camera, depth, gray_f32, points, pose, pose_matrix, Arr1, Arr2};
use crate::errors::{failed, release};

/// The `d` that moves the content of `img1` onto `img2`: `img2(x + d) = img1(x)`, pixels.
///
/// Robust coarse-to-fine Gauss-Newton over `levels` pyramid levels; with `affine_brightness`
/// also `img2(x + d) = a img1(x) + b`. Returns a dict: `d` (2,), `iterations` (all levels),
/// `iterations_per_level` (index 0 = full resolution), `rmse` (grey levels), `used_fraction`,
/// `covariance` (2x2, pixels^2), `a`, `b`, `converged`, `ms`.
#[pyfunction]
#[pyo3(signature = (img1, img2, levels = 4, max_iterations = 30, affine_brightness = false))]
pub fn align_translation<'py>(
    py: Python<'py>,
    img1: &Bound<'py, PyAny>,
    img2: &Bound<'py, PyAny>,
    levels: usize,
    max_iterations: usize,
    affine_brightness: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let (img1, img2) = (gray_f32(img1, "img1")?, gray_f32(img2, "img2")?);
    if levels == 0 || max_iterations == 0 {
        return Err(bad("levels and max_iterations must be positive"));
    }
    let cfg = TranslationConfig {
        levels,
        max_iterations,
        affine_brightness,
        ..TranslationConfig::default()
    };
    let (fit, ms) = release(py, || {
        let start = Instant::now();
        let fit = translation(&img1, &img2, &cfg).map_err(failed)?;
        Ok((fit, ms_since(start)))
    })?;
    let out = PyDict::new(py);
    out.set_item("d", PyArray1::from_slice(py, &[fit.d.x, fit.d.y]))?;
    out.set_item("iterations", fit.iterations.iter().sum::<usize>())?;
    out.set_item("iterations_per_level", fit.iterations)?;
    out.set_item("rmse", fit.rmse)?;
    out.set_item("used_fraction", fit.used_fraction)?;
    match fit.covariance {
        Some(cov) => {
            let cov = vec![cov[(0, 0)], cov[(0, 1)], cov[(1, 0)], cov[(1, 1)]];
            out.set_item("covariance", array2(py, 2, 2, cov))?;
        }
        None => out.set_item("covariance", py.None())?,
    }
    out.set_item("a", fit.a)?;
    out.set_item("b", fit.b)?;
    out.set_item("converged", fit.converged)?;
    out.set_item("ms", ms)?;
    Ok(out)
}

/// `CamelCase` to `snake_case`, for enum names in results.
fn snake(name: &str) -> String {
    let mut out = String::new();
    for (i, c) in name.chars().enumerate() {
        if c.is_uppercase() && i > 0 {
            out.push('_');
        }
        out.push(c.to_ascii_lowercase());
    }
    out
}

/// Rotation block `R` (3x3) and translation `t` (3,) of a pose.
pub fn rotation_translation<'py>(
    py: Python<'py>,
    p: &Isometry3<f64>,
) -> PyResult<(Arr2<'py, f64>, Arr1<'py, f64>)> {
    let r = p.rotation.to_rotation_matrix().into_inner();
    let rows: Vec<f64> = (0..3)
        .flat_map(|i| (0..3).map(move |j| r[(i, j)]))
        .collect();
    let t = p.translation.vector;
    Ok((
        array2(py, 3, 3, rows),
        PyArray1::from_slice(py, &[t.x, t.y, t.z]),
    ))
}

/// The pose `T_21` of the current camera relative to the reference (RGB-D) camera by direct
/// photometric alignment: `cur(pi(K T_21 pi^-1(p, Z(p)))) = a ref(p) + b` over the reference
/// pixels `p` with valid depth `Z` (metres).
///
/// `ref_depth`: uint16 raw units divided by `depth_scale` (5000 per metre, TUM), or
/// float32/float64 metres (0 or NaN = unknown). `prior`: initial 4x4 `T_21` (identity).
/// Returns a dict: `T_21` (4x4, translation in metres), `R`, `t`, `a`, `b`, `inlier_ratio`,
/// `rmse` and `sigma` (grey levels), `valid_pixels`, `iterations`, `covariance` (6x6 of the
/// left increment `(rho, phi)`, metres and radians), `reason` (why it stopped), `ms`.
#[pyfunction]
#[pyo3(signature = (ref_img, ref_depth, cur_img, K, dist = None, prior = None, depth_scale = 5000.0))]
#[allow(non_snake_case)]
#[allow(clippy::too_many_arguments)]
pub fn align_se3<'py>(
    py: Python<'py>,
    ref_img: &Bound<'py, PyAny>,
    ref_depth: &Bound<'py, PyAny>,
    cur_img: &Bound<'py, PyAny>,
    K: &Bound<'py, PyAny>,
    dist: Option<&Bound<'py, PyAny>>,
    prior: Option<&Bound<'py, PyAny>>,
    depth_scale: f64,
) -> PyResult<Bound<'py, PyDict>> {
    let reference = gray_f32(ref_img, "ref_img")?;
    let depth1 = depth(ref_depth, depth_scale, "ref_depth")?;
    let current = gray_f32(cur_img, "cur_img")?;
    let camera = camera(K, dist)?;
    let prior = match prior.filter(|p| !p.is_none()) {
        Some(p) => pose(p, "prior")?,
        None => Isometry3::identity(),
    };
    if reference.size() != current.size() {
        return Err(bad(format!(
            "cur_img: size {:?} differs from ref_img size {:?} (width, height)",
            current.size(),
            reference.size()
        )));
    }
    let (fit, ms) = release(py, || {
        let start = Instant::now();
        let frame = RgbdFrame::new(reference, depth1, &camera).map_err(failed)?;
        let fit = se3(&frame, &current, &prior, &Se3Config::default()).map_err(failed)?;
        Ok((fit, ms_since(start)))
    })?;
    let out = PyDict::new(py);
    out.set_item("T_21", pose_matrix(py, &fit.pose))?;
    let (r, t) = rotation_translation(py, &fit.pose)?;
    out.set_item("R", r)?;
    out.set_item("t", t)?;
    out.set_item("a", fit.a)?;
    out.set_item("b", fit.b)?;
    out.set_item("inlier_ratio", fit.inlier_ratio)?;
    out.set_item("rmse", fit.rmse)?;
    out.set_item("sigma", fit.sigma)?;
    out.set_item("valid_pixels", fit.valid_pixels)?;
    out.set_item("iterations", fit.iterations.iter().sum::<usize>())?;
    match &fit.covariance {
        Some(c) => {
            let cov: Vec<f64> = (0..6)
                .flat_map(|i| (0..6).map(move |j| c[(i, j)]))
                .collect();
            out.set_item("covariance", array2(py, 6, 6, cov))?;
        }
        None => out.set_item("covariance", py.None())?,
    }
    out.set_item("reason", snake(&format!("{:?}", fit.reason)))?;
    out.set_item("ms", ms)?;
    Ok(out)
}

/// `(next_points, status, error)` of [`klt`].
type KltOutput<'py> = (Arr2<'py, f32>, Arr1<'py, u8>, Arr1<'py, f32>);

/// Pyramidal Lucas-Kanade tracking of `points` ((N, 2) pixels in `img1`) into `img2`.
///
/// Returns `(next_points, status, error)` like OpenCV's `calcOpticalFlowPyrLK`:
/// `next_points` (N, 2) float32 pixels in `img2`, `status` (N,) uint8 (1 = tracked; 0 = left
/// the image, too little texture, or failed the forward-backward check of
/// `forward_backward` pixels, `None` disables it), `error` (N,) float32 mean absolute
/// residual over the window, grey levels.
#[pyfunction]
#[pyo3(signature = (img1, img2, points, window = 21, levels = 4, forward_backward = Some(1.0)))]
#[pyo3(text_signature = "(img1, img2, points, window=21, levels=4, forward_backward=1.0)")]
pub fn klt<'py>(
    py: Python<'py>,
    img1: &Bound<'py, PyAny>,
    img2: &Bound<'py, PyAny>,
    points: &Bound<'py, PyAny>,
    window: usize,
    levels: usize,
    forward_backward: Option<f32>,
) -> PyResult<KltOutput<'py>> {
    let (img1, img2) = (gray_f32(img1, "img1")?, gray_f32(img2, "img2")?);
    let start: Vec<Vector2<f32>> = self::points(points, "points")?
        .iter()
        .map(|p| p.cast::<f32>())
        .collect();
    let cfg = KltConfig {
        window,
        levels,
        forward_backward,
        ..KltConfig::default()
    };
    let tracks = release(py, || track_klt(&img1, &img2, &start, &cfg).map_err(failed))?;
    let positions = tracks
        .iter()
        .flat_map(|t| [t.position.x, t.position.y])
        .collect();
    let status: Vec<u8> = tracks
        .iter()
        .map(|t| u8::from(t.status == KltStatus::Tracked))
        .collect();
    let error: Vec<f32> = tracks.iter().map(|t| t.error).collect();
    Ok((
        array2(py, tracks.len(), 2, positions),
        PyArray1::from_vec(py, status),
        PyArray1::from_vec(py, error),
    ))
}
