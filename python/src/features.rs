//! `orb` and `match`: ORB keypoints and descriptors, Hamming matching with the ratio test.

use numpy::{PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;
use vofront::features::{match_descriptors, Descriptor, MatchConfig, Orb, OrbConfig};

use crate::convert::{array2, bad, gray8, Arr2};
use crate::errors::{failed, release};

/// Columns of the keypoint array returned by [`orb`].
const KEYPOINT_COLUMNS: usize = 6;

/// ORB features of a grey image.
///
/// Returns `(keypoints, descriptors)`: `keypoints` is `(N, 6)` float32 with columns
/// `x, y` (full-resolution pixels, pixel (0, 0) is the centre of the top-left pixel),
/// `scale` (level-0 pixels per level pixel), `angle` (radians, `atan2` of the intensity
/// centroid, y down), `response` (Harris), `level` (pyramid level); `descriptors` is `(N, 32)`
/// uint8 in OpenCV's bit order.
#[pyfunction]
#[pyo3(signature = (img, n = 2000))]
pub fn orb<'py>(
    py: Python<'py>,
    img: &Bound<'py, PyAny>,
    n: usize,
) -> PyResult<(Arr2<'py, f32>, Arr2<'py, u8>)> {
    let img = gray8(img, "img")?;
    let cfg = OrbConfig {
        n_features: n,
        ..OrbConfig::default()
    };
    let f = release(py, || {
        let orb = Orb::new(cfg).map_err(failed)?;
        orb.detect_and_describe(&img).map_err(failed)
    })?;
    let keypoints = (0..f.len())
        .flat_map(|i| {
            [
                f.xs()[i],
                f.ys()[i],
                f.scales()[i],
                f.angles()[i],
                f.responses()[i],
                f32::from(f.levels()[i]),
            ]
        })
        .collect();
    let descriptors = f
        .descriptors()
        .iter()
        .flat_map(Descriptor::to_bytes)
        .collect();
    Ok((
        array2(py, f.len(), KEYPOINT_COLUMNS, keypoints),
        array2(py, f.len(), 32, descriptors),
    ))
}

fn descriptors(a: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<Descriptor>> {
    let a: PyReadonlyArray2<'_, u8> = a.extract().map_err(|_| {
        bad(format!(
            "{what}: expected an (N, 32) uint8 array of ORB descriptors"
        ))
    })?;
    if a.shape()[1] != 32 {
        return Err(bad(format!(
            "{what}: expected shape (N, 32), got {:?}",
            a.shape()
        )));
    }
    let a = a.as_array();
    Ok(a.rows()
        .into_iter()
        .map(|row| {
            let mut bytes = [0u8; 32];
            for (b, v) in bytes.iter_mut().zip(row.iter()) {
                *b = *v;
            }
            Descriptor::from_bytes(&bytes)
        })
        .collect())
}

/// Matches descriptors `d1` (query) against `d2` (train) by Hamming distance.
///
/// Keeps the nearest neighbour when it passes Lowe's ratio test `d_best < ratio * d_second`
/// (`ratio=None` disables it), is within `max_distance` bits, and with `cross_check` is also
/// mutual. Returns an `(M, 3)` int64 array of `query, train, distance` rows.
#[pyfunction(name = "match")]
#[pyo3(signature = (d1, d2, ratio = Some(0.75), cross_check = false, max_distance = 100))]
#[pyo3(text_signature = "(d1, d2, ratio=0.75, cross_check=False, max_distance=100)")]
pub fn match_<'py>(
    py: Python<'py>,
    d1: &Bound<'py, PyAny>,
    d2: &Bound<'py, PyAny>,
    ratio: Option<f32>,
    cross_check: bool,
    max_distance: u32,
) -> PyResult<Arr2<'py, i64>> {
    if ratio.is_some_and(|r| !(r > 0.0 && r <= 1.0)) {
        return Err(bad(format!("ratio must be in (0, 1], got {ratio:?}")));
    }
    let (q, t) = (descriptors(d1, "d1")?, descriptors(d2, "d2")?);
    let cfg = MatchConfig {
        ratio,
        cross_check,
        max_distance,
    };
    let matches = release(py, || Ok(match_descriptors(&q, &t, &cfg)))?;
    let data = matches
        .iter()
        .flat_map(|m| [m.query, m.train, m.distance].map(i64::from))
        .collect();
    Ok(array2(py, matches.len(), 3, data))
}
