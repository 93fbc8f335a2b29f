//! KITTI odometry sequence folders (`sequences/XX/`).
//!
//! Layout: `image_0/NNNNNN.png` (left grey camera, six-digit frame index), `times.txt`
//! (one timestamp in seconds per frame), `calib.txt` (lines `Pk: ` + 12 numbers, the 3x4
//! row-major projection matrix; the camera is read from `P0`: `fx = P[0]`, `cx = P[2]`,
//! `fy = P[5]`, `cy = P[6]`, no distortion: the images are rectified). Ground truth, optional:
//! `poses.txt` in the folder, `poses/XX.txt` in the folder, or the standard
//! `../../poses/XX.txt`, 12 numbers per line (3x4 row-major camera-to-world `T_wc` of
//! camera 0), one line per frame.

use std::path::{Path, PathBuf};

use vofront_geometry::camera::{Camera, Pinhole};

use super::{
    parse_error, read_text, CameraSource, Dataset, DatasetConfig, DatasetError, DatasetKind,
    FrameInfo,
};
use crate::trajectory::{data_lines, parse_numbers, parse_times, Trajectory};

/// Opens a KITTI odometry sequence folder (see the module documentation).
pub fn open(root: &Path, config: &DatasetConfig) -> Result<Dataset, DatasetError> {
    let calib = root.join("calib.txt");
    if !calib.is_file() {
        return Err(DatasetError::MissingCalibration { path: calib });
    }
    let camera = read_p0(&calib)?;
    let times_path = root.join("times.txt");
    let times = parse_times(&read_text(&times_path)?, &times_path)?;
    let frames = times
        .iter()
        .enumerate()
        .map(|(i, &timestamp)| FrameInfo {
            timestamp,
            image: root.join(format!("image_0/{i:06}.png")),
            depth: None,
        })
        .collect();
    let ground_truth = match poses_file(root) {
        Some(p) => Some(Trajectory::read_kitti(&p, Some(&times_path))?),
        None => None,
    };
    Ok(Dataset {
        kind: DatasetKind::Kitti,
        root: root.to_path_buf(),
        frames,
        camera: Some(camera),
        camera_source: Some(CameraSource::CalibrationFile(calib)),
        depth_scale: None,
        ground_truth,
        ground_truth_tolerance: config.ground_truth_tolerance,
        camera_in_body: None,
    })
}

/// The first existing ground-truth candidate among `poses.txt`, `poses/XX.txt` and
/// `../../poses/XX.txt`, `XX` the folder name.
fn poses_file(root: &Path) -> Option<PathBuf> {
    let mut candidates = vec![root.join("poses.txt")];
    if let Some(seq) = root.file_name() {
        let file = Path::new(seq).with_extension("txt");
        candidates.push(root.join("poses").join(&file));
        if let Some(base) = root.parent().and_then(Path::parent) {
            candidates.push(base.join("poses").join(&file));
        }
    }
    candidates.into_iter().find(|p| p.is_file())
}

/// The pinhole camera of the `P0:` line of `calib.txt`.
fn read_p0(path: &Path) -> Result<Camera, DatasetError> {
    let text = read_text(path)?;
    for (line, fields) in data_lines(&text) {
        if fields.first() != Some(&"P0:") {
            continue;
        }
        if fields.len() != 13 {
            return Err(parse_error(
                path,
                line,
                format!("P0 needs 12 numbers, found {}", fields.len() - 1),
            ));
        }
        let p = parse_numbers(&fields[1..]).map_err(|m| parse_error(path, line, m))?;
        let pinhole =
            Pinhole::new(p[0], p[5], p[2], p[6]).map_err(|source| DatasetError::Camera {
                path: path.to_path_buf(),
                source,
            })?;
        return Ok(Camera::pinhole(pinhole));
    }
    Err(parse_error(path, 0, "no `P0:` line"))
}
