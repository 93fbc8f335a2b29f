//! KITTI odometry sequence folders (`sequences/XX/`).
//!
//! Layout: `image_0/*.png` (left grey camera, usually `NNNNNN.png`), `times.txt` (one
//! timestamp in seconds per frame), `calib.txt` (lines `Pk: ` + 12 numbers, the 3x4
//! row-major projection matrix; the camera is read from `P0`: `fx = P[0]`, `cx = P[2]`,
//! `fy = P[5]`, `cy = P[6]`, no distortion: the images are rectified). The `.png` files of
//! `image_0/`, sorted by name, are paired in order with the lines of `times.txt`, whatever
//! their numbering (an excerpt may start at `000100.png`); different counts are a
//! [`DatasetError::FrameCount`].
//!
//! Stereo, when `image_1/` exists: the right image of each frame has the left one's file name
//! in `image_1/` (a missing one is a [`DatasetError::MissingRightImage`] at open), the right
//! camera is read from `P1` like `P0`, and the baseline from `P1 = [fx 0 cx -fx b; ...]`:
//! `b = -P1[3] / P1[0]` (metres). The rig's body frame is the left camera: `T_BS` is the
//! identity for the left camera and the translation `(b, 0, 0)` for the right one (its centre
//! is `b` to the right of the left camera's, both rectified, same orientation).
//!
//! Ground truth, optional:
//! `poses.txt` in the folder, `poses/XX.txt` in the folder, or the standard
//! `../../poses/XX.txt`, 12 numbers per line (3x4 row-major camera-to-world `T_wc` of
//! camera 0), one line per frame.

use std::path::{Path, PathBuf};

use nalgebra::Isometry3;
use vofront_core::camera::{Camera, Pinhole};
use vofront_core::rig::Rig;

use super::{
    mono_rig, parse_error, read_text, CameraSource, Dataset, DatasetConfig, DatasetError,
    DatasetKind, FrameInfo,
};
use crate::trajectory::{data_lines, parse_numbers, parse_times, Trajectory};

/// Opens a KITTI odometry sequence folder (see the module documentation).
pub fn open(root: &Path, config: &DatasetConfig) -> Result<Dataset, DatasetError> {
    let calib = root.join("calib.txt");
    if !calib.is_file() {
        return Err(DatasetError::MissingCalibration { path: calib });
    }
    let (camera, _) = read_projection(&calib, "P0")?;
    let times_path = root.join("times.txt");
    let times = parse_times(&read_text(&times_path)?, &times_path)?;
    let left_dir = root.join("image_0");
    let images = list_png(&left_dir)?;
    if images.len() != times.len() {
        return Err(DatasetError::FrameCount {
            images_dir: left_dir,
            images: images.len(),
            times_file: times_path,
            times: times.len(),
        });
    }
    let right_dir = root.join("image_1");
    let stereo = right_dir.is_dir();
    let frames = times
        .iter()
        .zip(images)
        .map(|(&timestamp, image)| {
            let right = match image.file_name() {
                Some(name) if stereo => {
                    let right = right_dir.join(name);
                    if !right.is_file() {
                        return Err(DatasetError::MissingRightImage {
                            path: right,
                            left: image,
                        });
                    }
                    Some(right)
                }
                _ => None,
            };
            Ok(FrameInfo {
                timestamp,
                image,
                depth: None,
                right,
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    let rig = if stereo {
        let (right, baseline) = read_projection(&calib, "P1")?;
        Rig::stereo(
            camera,
            Isometry3::identity(),
            right,
            Isometry3::translation(baseline, 0.0, 0.0),
        )
        .map(Some)
        .map_err(|source| DatasetError::Rig {
            path: calib.clone(),
            source,
        })?
    } else {
        mono_rig(Some(camera), None, &calib)?
    };
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
        rig,
        bag: Default::default(),
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

/// The `.png` files of `dir`, sorted by name.
fn list_png(dir: &Path) -> Result<Vec<PathBuf>, DatasetError> {
    let entries = std::fs::read_dir(dir).map_err(|source| DatasetError::Io {
        path: dir.to_path_buf(),
        source,
    })?;
    let mut files: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file() && p.extension().is_some_and(|e| e.eq_ignore_ascii_case("png")))
        .collect();
    files.sort();
    Ok(files)
}

/// The pinhole camera of the `name:` line (`P0`, `P1`) of `calib.txt` and its baseline
/// `-P[3] / P[0]` (metres; 0 for `P0`).
fn read_projection(path: &Path, name: &str) -> Result<(Camera, f64), DatasetError> {
    let text = read_text(path)?;
    let key = format!("{name}:");
    for (line, fields) in data_lines(&text) {
        if fields.first() != Some(&key.as_str()) {
            continue;
        }
        if fields.len() != 13 {
            return Err(parse_error(
                path,
                line,
                format!("{name} needs 12 numbers, found {}", fields.len() - 1),
            ));
        }
        let p = parse_numbers(&fields[1..]).map_err(|m| parse_error(path, line, m))?;
        let pinhole =
            Pinhole::new(p[0], p[5], p[2], p[6]).map_err(|source| DatasetError::Camera {
                path: path.to_path_buf(),
                source,
            })?;
        return Ok((Camera::pinhole(pinhole), -p[3] / p[0]));
    }
    Err(parse_error(path, 0, format!("no `{name}:` line")))
}
