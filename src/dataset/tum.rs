//! TUM RGB-D benchmark folders.
//!
//! Layout: `rgb.txt` and optional `depth.txt` (`timestamp filename` lines, `#` comments,
//! file names relative to the folder), 8-bit colour images, 16-bit depth PNGs in units of
//! 1/5000 m (0 = no depth), optional `groundtruth.txt` (TUM trajectory of the camera,
//! `T_wc`). Each image is paired with the depth map nearest in time within
//! [`DatasetConfig::depth_tolerance`]; an image without one gets `depth: None`.
//! There is no calibration file: [`Dataset::camera`] is the freiburg1/2/3 preset that the
//! folder name names (`rgbd_dataset_freiburg1_xyz`), else the one named in the `# file:
//! 'rgbd_dataset_freiburgN_....bag'` header line of `rgb.txt`, `depth.txt` or
//! `groundtruth.txt` (as the benchmark ships them), else `None`.

use std::path::Path;

use vofront_core::camera::{Camera, Distortion, Pinhole};

use super::{
    parse_error, read_text, CameraSource, Dataset, DatasetConfig, DatasetError, DatasetKind,
    FrameInfo,
};
use crate::trajectory::{associate_stamps, data_lines, parse_numbers, Trajectory};

/// TUM depth PNG units per metre.
pub const TUM_DEPTH_SCALE: f64 = 5000.0;

/// Opens a TUM RGB-D folder (see the module documentation).
pub fn open(root: &Path, config: &DatasetConfig) -> Result<Dataset, DatasetError> {
    let rgb = read_list(root, "rgb.txt")?;
    let depth_list = root.join("depth.txt");
    let depth = if depth_list.is_file() {
        read_list(root, "depth.txt")?
    } else {
        Vec::new()
    };
    let mut frames: Vec<FrameInfo> = rgb
        .into_iter()
        .map(|(timestamp, image)| FrameInfo {
            timestamp,
            image,
            depth: None,
            right: None,
        })
        .collect();
    let rgb_stamps: Vec<f64> = frames.iter().map(|f| f.timestamp).collect();
    let depth_stamps: Vec<f64> = depth.iter().map(|d| d.0).collect();
    for (i, j) in associate_stamps(&rgb_stamps, &depth_stamps, config.depth_tolerance) {
        frames[i].depth = Some(depth[j].1.clone());
    }
    let gt_path = root.join("groundtruth.txt");
    let ground_truth = if gt_path.is_file() {
        Some(Trajectory::read_tum(&gt_path)?)
    } else {
        None
    };
    let (camera, camera_source) = match detect_camera(root) {
        Some((camera, source)) => (Some(camera), Some(source)),
        None => (None, None),
    };
    Ok(Dataset {
        kind: DatasetKind::Tum,
        root: root.to_path_buf(),
        frames,
        rig: super::mono_rig(camera, None, root)?,
        bag: Default::default(),
        camera,
        camera_source,
        depth_scale: depth_list.is_file().then_some(TUM_DEPTH_SCALE),
        ground_truth,
        ground_truth_tolerance: config.ground_truth_tolerance,
        camera_in_body: None,
    })
}

/// The TUM camera of the folder `root` and where it was named (see the module documentation).
pub fn detect_camera(root: &Path) -> Option<(Camera, CameraSource)> {
    let name = root
        .canonicalize()
        .ok()
        .and_then(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
        .or_else(|| root.file_name().map(|n| n.to_string_lossy().into_owned()))?;
    if let Some(k) = freiburg_number(&name) {
        return Some((
            freiburg(k),
            CameraSource::FolderName(format!("freiburg{k}")),
        ));
    }
    ["rgb.txt", "depth.txt", "groundtruth.txt"]
        .iter()
        .find_map(|file| {
            let path = root.join(file);
            let text = std::fs::read_to_string(&path).ok()?;
            let header = text
                .lines()
                .take_while(|l| l.trim_start().starts_with('#') || l.trim().is_empty())
                .find(|l| l.contains("file:"))?;
            let k = freiburg_number(header)?;
            Some((freiburg(k), CameraSource::FileHeader(path)))
        })
}

/// `1`, `2` or `3` when `text` contains `freiburg1`, `freiburg2` or `freiburg3` (any case).
fn freiburg_number(text: &str) -> Option<u8> {
    let lower = text.to_ascii_lowercase();
    (1..=3).find(|k| lower.contains(&format!("freiburg{k}")))
}

/// The published calibration of TUM camera freiburg `k` (1, 2 or 3).
fn freiburg(k: u8) -> Camera {
    let (pinhole, d) = match k {
        1 => (
            (517.3, 516.5, 318.6, 255.3),
            [0.2624, -0.9531, -0.0054, 0.0026, 1.1633],
        ),
        2 => (
            (520.9, 521.0, 325.1, 249.7),
            [0.2312, -0.7849, -0.0033, -0.0001, 0.9172],
        ),
        _ => ((535.4, 539.2, 320.1, 247.6), [0.0; 5]),
    };
    let (fx, fy, cx, cy) = pinhole;
    Camera::new(Pinhole { fx, fy, cx, cy }, Distortion::from_array(d))
}

/// The published calibration of the TUM camera named in the folder name
/// (`..._freiburg1_...`, `freiburg2`, `freiburg3`), `None` for any other name.
///
/// fr1: `517.3 516.5 318.6 255.3`, distortion `0.2624 -0.9531 -0.0054 0.0026 1.1633`;
/// fr2: `520.9 521.0 325.1 249.7`, distortion `0.2312 -0.7849 -0.0033 -0.0001 0.9172`;
/// fr3: `535.4 539.2 320.1 247.6`, no distortion (from the benchmark's file-format page).
pub fn tum_preset_for(path: &Path) -> Option<Camera> {
    let name = path.file_name()?.to_str()?;
    freiburg_number(name).map(freiburg)
}

/// `(timestamp, root/filename)` lines of a TUM list file.
fn read_list(root: &Path, name: &str) -> Result<Vec<(f64, std::path::PathBuf)>, DatasetError> {
    let path = root.join(name);
    let text = read_text(&path)?;
    data_lines(&text)
        .map(|(line, fields)| match fields.as_slice() {
            [stamp, file] => {
                let t = parse_numbers(&[stamp]).map_err(|m| parse_error(&path, line, m))?;
                Ok((t[0], root.join(file)))
            }
            _ => Err(parse_error(
                &path,
                line,
                format!(
                    "expected `timestamp filename`, found {} fields",
                    fields.len()
                ),
            )),
        })
        .collect()
}
