//! Library errors as Python exceptions, and running Rust work without the GIL and without
//! letting a panic reach the interpreter.
//!
//! - bad arrays or parameters: `ValueError` (raised in [`crate::convert`]);
//! - an estimator that fails on valid input (too few matches, flat image, ...):
//!   `vofront.VofrontError`, a subclass of `ValueError`, with the library's message;
//! - files that cannot be read: `OSError` (`FileNotFoundError` when missing);
//! - a panic inside Rust: `RuntimeError` naming it an internal error.

use std::any::Any;
use std::io;
use std::panic::{catch_unwind, AssertUnwindSafe};

use pyo3::create_exception;
use pyo3::exceptions::{PyFileNotFoundError, PyOSError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use vofront::dataset::DatasetError;
use vofront::trajectory::TrajectoryError;

create_exception!(
    _vofront,
    VofrontError,
    PyValueError,
    "An estimator failed on valid input (the message is the library's)."
);

/// `VofrontError` with the library's message.
pub fn failed(e: impl std::fmt::Display) -> PyErr {
    VofrontError::new_err(e.to_string())
}

/// An I/O error: `FileNotFoundError` when the file is missing, `OSError` otherwise.
pub fn io_error(e: &io::Error, msg: String) -> PyErr {
    if e.kind() == io::ErrorKind::NotFound {
        PyFileNotFoundError::new_err(msg)
    } else {
        PyOSError::new_err(msg)
    }
}

/// A trajectory file error: `OSError` (missing or unreadable file, bad line).
pub fn trajectory_error(e: TrajectoryError) -> PyErr {
    match &e {
        TrajectoryError::Io { source, .. } => io_error(source, e.to_string()),
        _ => PyOSError::new_err(e.to_string()),
    }
}

/// A dataset error: `OSError` for the folder and its files, `ValueError` for a bad index.
pub fn dataset_error(e: DatasetError) -> PyErr {
    match e {
        DatasetError::Io { ref source, .. } => io_error(source, e.to_string()),
        DatasetError::Trajectory(t) => trajectory_error(t),
        DatasetError::FrameIndex { .. } => PyValueError::new_err(e.to_string()),
        _ => PyOSError::new_err(e.to_string()),
    }
}

fn panic_message(payload: &(dyn Any + Send)) -> &str {
    payload
        .downcast_ref::<&str>()
        .copied()
        .or_else(|| payload.downcast_ref::<String>().map(String::as_str))
        .unwrap_or("unknown panic")
}

/// Runs `f` with the GIL released; a panic becomes a `RuntimeError` instead of unwinding into
/// the interpreter.
pub fn release<T, F>(py: Python<'_>, f: F) -> PyResult<T>
where
    T: Send,
    F: FnOnce() -> PyResult<T> + Send,
{
    py.allow_threads(|| catch_unwind(AssertUnwindSafe(f)))
        .unwrap_or_else(|payload| {
            Err(PyRuntimeError::new_err(format!(
                "vofront internal error (a bug, please report it): {}",
                panic_message(payload.as_ref())
            )))
        })
}
