//! `vofront._vofront`: the Python bindings of vofront (the package `vofront` re-exports it).
//!
//! Pose convention: `T_21` maps frame-1 points into frame 2, `x2 = R x1 + t`, returned as a 4x4
//! float64 matrix; trajectories are camera-to-world (`T_wc`). Images are 2-D uint8 or float32
//! arrays of grey levels (0..255), `K` a 3x3 intrinsic matrix in pixels, `dist` OpenCV's
//! `(k1, k2, p1, p2, k3)`. The GIL is released while Rust computes; bad input raises
//! `ValueError`, an estimator failure `vofront.VofrontError` (a `ValueError`), unreadable
//! files `OSError`.

mod compare;
mod convert;
mod direct;
mod errors;
mod eval;
mod features;
mod input;
mod odometry;
mod two_view;

use pyo3::prelude::*;

/// The compiled module.
#[pymodule]
fn _vofront(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("VofrontError", m.py().get_type::<errors::VofrontError>())?;
    m.add_function(wrap_pyfunction!(two_view::two_view, m)?)?;
    m.add_function(wrap_pyfunction!(two_view::relpose, m)?)?;
    m.add_function(wrap_pyfunction!(features::orb, m)?)?;
    m.add_function(wrap_pyfunction!(features::match_, m)?)?;
    m.add_function(wrap_pyfunction!(direct::align_translation, m)?)?;
    m.add_function(wrap_pyfunction!(direct::align_se3, m)?)?;
    m.add_function(wrap_pyfunction!(direct::klt, m)?)?;
    m.add_class::<odometry::Odometry>()?;
    m.add_function(wrap_pyfunction!(odometry::run_odometry, m)?)?;
    m.add_function(wrap_pyfunction!(compare::compare, m)?)?;
    m.add_function(wrap_pyfunction!(eval::ate, m)?)?;
    m.add_function(wrap_pyfunction!(eval::rpe, m)?)?;
    m.add_function(wrap_pyfunction!(input::load_gray, m)?)?;
    m.add_function(wrap_pyfunction!(input::load_depth, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
