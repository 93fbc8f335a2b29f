//! numpy in, numpy out: images, depth maps, intrinsics, poses and point lists.
//!
//! Every input is checked here (dtype, shape, finiteness) and rejected with a `ValueError`
//! naming the argument; an image is read exactly once, converted into the buffer the library
//! owns (`uint8` for the feature pipeline, `f32` for the direct aligners).

use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector2};
use numpy::ndarray::{Array2, ArrayView2};
use numpy::{
    AllowTypeChange, IntoPyArray, PyArray2, PyArrayLike2, PyArrayLikeDyn, PyReadonlyArray2,
    PyUntypedArrayMethods,
};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use serde_json::Value;
use vofront::core::camera::{Camera, Distortion, Pinhole};
use vofront::image::Image;

/// A 1-D numpy array owned by Python.
pub type Arr1<'py, T> = Bound<'py, numpy::PyArray1<T>>;
/// A 2-D numpy array owned by Python.
pub type Arr2<'py, T> = Bound<'py, PyArray2<T>>;

/// A `ValueError` with `msg`.
pub fn bad(msg: impl Into<String>) -> PyErr {
    PyValueError::new_err(msg.into())
}

/// `(rows, cols)` of a 2-D array, rejecting empty arrays and sizes beyond `u32`.
fn image_shape(shape: &[usize], what: &str) -> PyResult<(usize, usize)> {
    let (h, w) = (shape[0], shape[1]);
    if h == 0 || w == 0 || u32::try_from(h.max(w)).is_err() {
        return Err(bad(format!(
            "{what}: image of shape {h}x{w} is empty or too large"
        )));
    }
    Ok((h, w))
}

/// The values of a 2-D array in row-major order: one copy, whatever the strides.
fn to_vec<T: Copy>(a: ArrayView2<'_, T>) -> Vec<T> {
    match a.as_slice() {
        Some(s) => s.to_vec(),
        None => a.iter().copied().collect(),
    }
}

/// Describes an object that is not an array of the expected kind, for error messages.
fn describe(obj: &Bound<'_, PyAny>) -> String {
    match obj.downcast::<numpy::PyUntypedArray>() {
        Ok(a) => format!("an array of dtype {} and shape {:?}", a.dtype(), a.shape()),
        Err(_) => format!(
            "a {}",
            obj.get_type()
                .name()
                .map_or_else(|_| "?".into(), |n| n.to_string())
        ),
    }
}

/// The pixels of a `(H, W)` grey image array, borrowed from numpy.
enum Pixels<'py> {
    U8(PyReadonlyArray2<'py, u8>),
    F32(PyReadonlyArray2<'py, f32>),
}

/// Borrows a `(H, W)` `uint8` or `float32` (finite grey levels, 0..255) array.
fn pixels<'py>(obj: &Bound<'py, PyAny>, what: &str) -> PyResult<(Pixels<'py>, (usize, usize))> {
    let (px, shape) = if let Ok(a) = obj.extract::<PyReadonlyArray2<'py, u8>>() {
        let shape = image_shape(a.shape(), what)?;
        (Pixels::U8(a), shape)
    } else if let Ok(a) = obj.extract::<PyReadonlyArray2<'py, f32>>() {
        let shape = image_shape(a.shape(), what)?;
        if !a.as_array().iter().all(|v| v.is_finite()) {
            return Err(bad(format!(
                "{what}: image contains NaN or infinite values"
            )));
        }
        (Pixels::F32(a), shape)
    } else {
        return Err(bad(format!(
            "{what}: expected a 2-D uint8 or float32 grey image (H, W), got {}",
            describe(obj)
        )));
    };
    Ok((px, shape))
}

/// The 8-bit image the feature pipeline takes, in one pass over the array (`float32` values
/// rounded and clamped to 0..255).
pub fn gray8(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Image<u8>> {
    let (px, (h, w)) = pixels(obj, what)?;
    let data = match px {
        Pixels::U8(a) => to_vec(a.as_array()),
        Pixels::F32(a) => a
            .as_array()
            .iter()
            .map(|&v| v.round().clamp(0.0, 255.0) as u8)
            .collect(),
    };
    Image::new(w, h, data).map_err(|e| bad(format!("{what}: {e}")))
}

/// The `f32` grey levels the direct aligners take, in one pass over the array.
pub fn gray_f32(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Image<f32>> {
    let (px, (h, w)) = pixels(obj, what)?;
    let data = match px {
        Pixels::U8(a) => a.as_array().iter().map(|&v| f32::from(v)).collect(),
        Pixels::F32(a) => to_vec(a.as_array()),
    };
    Image::new(w, h, data).map_err(|e| bad(format!("{what}: {e}")))
}

/// Metric depth values (metres, 0 = unknown) of a `(H, W)` array: `uint16` raw sensor units
/// divided by `scale` (5000 per metre for TUM), or `float32` / `float64` metres (non-finite
/// values become 0 = unknown). Returns `(width, height, row-major values)`.
fn depth_values(
    obj: &Bound<'_, PyAny>,
    scale: f64,
    what: &str,
) -> PyResult<(usize, usize, Vec<f32>)> {
    if let Ok(a) = obj.extract::<PyReadonlyArray2<'_, u16>>() {
        if !(scale.is_finite() && scale > 0.0) {
            return Err(bad(format!("depth_scale must be positive, got {scale}")));
        }
        let (h, w) = image_shape(a.shape(), what)?;
        let metres = a
            .as_array()
            .iter()
            .map(|&v| (v as f64 / scale) as f32)
            .collect();
        return Ok((w, h, metres));
    }
    if let Ok(a) = obj.extract::<PyReadonlyArray2<'_, f32>>() {
        let (h, w) = image_shape(a.shape(), what)?;
        let finite = |v: f32| if v.is_finite() { v } else { 0.0 };
        let metres = a.as_array().iter().map(|&v| finite(v)).collect();
        return Ok((w, h, metres));
    }
    if let Ok(a) = obj.extract::<PyReadonlyArray2<'_, f64>>() {
        let (h, w) = image_shape(a.shape(), what)?;
        let finite = |v: f64| if v.is_finite() { v as f32 } else { 0.0 };
        let metres = a.as_array().iter().map(|&v| finite(v)).collect();
        return Ok((w, h, metres));
    }
    Err(bad(format!(
        "{what}: expected a 2-D uint16 (raw units) or float32/float64 (metres) depth map, got {}",
        describe(obj)
    )))
}

/// A metric depth map (see [`depth_values`]): metres, 0 = unknown.
pub fn depth(obj: &Bound<'_, PyAny>, scale: f64, what: &str) -> PyResult<Image<f32>> {
    let (w, h, metres) = depth_values(obj, scale, what)?;
    Image::new(w, h, metres).map_err(|e| bad(format!("{what}: {e}")))
}

/// A `(rows, cols)` float64 matrix from anything numpy converts, checked for finiteness.
fn matrix<'py>(
    obj: &Bound<'py, PyAny>,
    rows: usize,
    cols: usize,
    what: &str,
) -> PyResult<Array2<f64>> {
    let a: PyArrayLike2<'py, f64, AllowTypeChange> = obj.extract().map_err(|_| {
        bad(format!(
            "{what}: expected a {rows}x{cols} array of numbers, got {}",
            describe(obj)
        ))
    })?;
    let a = a.as_array();
    if a.dim() != (rows, cols) {
        return Err(bad(format!(
            "{what}: expected shape ({rows}, {cols}), got {:?}",
            a.shape()
        )));
    }
    if !a.iter().all(|v| v.is_finite()) {
        return Err(bad(format!("{what}: contains NaN or infinite values")));
    }
    Ok(a.to_owned())
}

/// The camera of a 3x3 intrinsic matrix `K = [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]` (pixels)
/// and optional OpenCV distortion `(k1, k2, p1, p2[, k3])` (further coefficients must be 0).
pub fn camera(k: &Bound<'_, PyAny>, dist: Option<&Bound<'_, PyAny>>) -> PyResult<Camera> {
    let m = matrix(k, 3, 3, "K")?;
    let zero = |v: f64| v.abs() <= 1e-12;
    if !(zero(m[(0, 1)]) && zero(m[(1, 0)]) && zero(m[(2, 0)]) && zero(m[(2, 1)])) {
        return Err(bad(
            "K: expected [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] (no skew)",
        ));
    }
    if (m[(2, 2)] - 1.0).abs() > 1e-12 {
        return Err(bad(format!("K: K[2, 2] must be 1, got {}", m[(2, 2)])));
    }
    let pinhole = Pinhole::new(m[(0, 0)], m[(1, 1)], m[(0, 2)], m[(1, 2)])
        .map_err(|e| bad(format!("K: {e}")))?;
    let mut coefficients = [0.0; 5];
    if let Some(d) = dist.filter(|d| !d.is_none()) {
        let a: PyArrayLikeDyn<'_, f64, AllowTypeChange> = d.extract().map_err(|_| {
            bad(format!(
                "dist: expected an array of numbers, got {}",
                describe(d)
            ))
        })?;
        let values: Vec<f64> = a.as_array().iter().copied().collect();
        if values.len() > 5 && values[5..].iter().any(|&v| v != 0.0) {
            return Err(bad(
                "dist: only the radial-tangential model (k1, k2, p1, p2, k3) is supported",
            ));
        }
        for (c, v) in coefficients.iter_mut().zip(&values) {
            *c = *v;
        }
    }
    let camera = Camera::new(pinhole, Distortion::from_array(coefficients));
    camera.validate().map_err(|e| bad(format!("camera: {e}")))?;
    Ok(camera)
}

/// A rigid pose from a 4x4 homogeneous matrix `[[R, t], [0, 0, 0, 1]]` with orthonormal `R`.
pub fn pose(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Isometry3<f64>> {
    let m = matrix(obj, 4, 4, what)?;
    let last_row_ok = (0..3).all(|c| m[(3, c)].abs() <= 1e-9) && (m[(3, 3)] - 1.0).abs() <= 1e-9;
    let r = Matrix3::from_fn(|i, j| m[(i, j)]);
    let orthonormal = (r.transpose() * r - Matrix3::identity()).norm() <= 1e-6;
    if !last_row_ok || !orthonormal || r.determinant() <= 0.0 {
        return Err(bad(format!(
            "{what}: expected a rigid 4x4 pose [[R, t], [0, 0, 0, 1]] with R a rotation"
        )));
    }
    let rotation = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r));
    let translation = Translation3::new(m[(0, 3)], m[(1, 3)], m[(2, 3)]);
    Ok(Isometry3::from_parts(translation, rotation))
}

/// `(N, 2)` pixel coordinates from anything numpy converts.
pub fn points(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<Vector2<f64>>> {
    let a: PyArrayLike2<'_, f64, AllowTypeChange> = obj.extract().map_err(|_| {
        bad(format!(
            "{what}: expected an (N, 2) array of pixel coordinates, got {}",
            describe(obj)
        ))
    })?;
    let a = a.as_array();
    if a.ncols() != 2 {
        return Err(bad(format!(
            "{what}: expected shape (N, 2), got {:?}",
            a.shape()
        )));
    }
    let out: Vec<_> = a
        .rows()
        .into_iter()
        .map(|r| Vector2::new(r[0], r[1]))
        .collect();
    if !out.iter().all(|p| p.x.is_finite() && p.y.is_finite()) {
        return Err(bad(format!("{what}: contains NaN or infinite values")));
    }
    Ok(out)
}

/// The 4x4 homogeneous matrix of a pose, float64.
pub fn pose_matrix<'py>(py: Python<'py>, pose: &Isometry3<f64>) -> Bound<'py, PyArray2<f64>> {
    let m = pose.to_homogeneous();
    Array2::from_shape_fn((4, 4), |(i, j)| m[(i, j)]).into_pyarray(py)
}

/// A row-major `(rows, cols)` array of `data`.
pub fn array2<'py, T: numpy::Element>(
    py: Python<'py>,
    rows: usize,
    cols: usize,
    data: Vec<T>,
) -> Bound<'py, PyArray2<T>> {
    Array2::from_shape_vec((rows, cols), data)
        .expect("rows * cols values")
        .into_pyarray(py)
}

/// A JSON value as plain Python objects (dict, list, float, int, str, bool, None).
pub fn json_to_py<'py>(py: Python<'py>, v: &Value) -> PyResult<Bound<'py, PyAny>> {
    Ok(match v {
        Value::Null => py.None().into_bound(py),
        Value::Bool(b) => b.into_pyobject(py)?.to_owned().into_any(),
        Value::Number(n) => match (n.as_u64(), n.as_i64()) {
            (Some(u), _) => u.into_pyobject(py)?.into_any(),
            (None, Some(i)) => i.into_pyobject(py)?.into_any(),
            _ => n.as_f64().unwrap_or(f64::NAN).into_pyobject(py)?.into_any(),
        },
        Value::String(s) => s.into_pyobject(py)?.into_any(),
        Value::Array(items) => {
            let list = PyList::empty(py);
            for item in items {
                list.append(json_to_py(py, item)?)?;
            }
            list.into_any()
        }
        Value::Object(map) => {
            let dict = PyDict::new(py);
            for (k, item) in map {
                dict.set_item(k, json_to_py(py, item)?)?;
            }
            dict.into_any()
        }
    })
}
