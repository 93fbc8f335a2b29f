//! Reading image files into numpy: `load_gray` and `load_depth`.

use std::path::PathBuf;

use pyo3::exceptions::PyOSError;
use pyo3::prelude::*;
use vofront::input::{load_depth as depth_of, load_gray as gray_of, InputError};

use crate::convert::{array2, bad, Arr2};
use crate::errors::{io_error, release};

fn input_error(e: InputError) -> PyErr {
    match &e {
        InputError::Read { source, .. } => io_error(source, e.to_string()),
        _ => PyOSError::new_err(e.to_string()),
    }
}

/// A PNG or JPEG file as a (H, W) uint8 grey image (colour converted with Rec. 601 luma),
/// exactly as `vofront two-view` reads it.
#[pyfunction]
pub fn load_gray<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Arr2<'py, u8>> {
    let img = release(py, || gray_of(&path).map_err(input_error))?;
    let (w, h) = img.size();
    Ok(array2(py, h, w, img.into_data()))
}

/// A 16-bit (or 8-bit) depth PNG as (H, W) float32 metres: value / `depth_scale` (5000 per
/// metre for TUM), 0 = unknown.
#[pyfunction]
#[pyo3(signature = (path, depth_scale = 5000.0))]
pub fn load_depth<'py>(
    py: Python<'py>,
    path: PathBuf,
    depth_scale: f64,
) -> PyResult<Arr2<'py, f32>> {
    if !(depth_scale.is_finite() && depth_scale > 0.0) {
        return Err(bad(format!(
            "depth_scale must be positive, got {depth_scale}"
        )));
    }
    let depth = release(py, || depth_of(&path, depth_scale).map_err(input_error))?;
    let (w, h) = depth.size();
    Ok(array2(py, h, w, depth.into_data()))
}
