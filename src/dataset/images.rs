//! A plain folder of images (`.png`, `.jpg`, `.jpeg`, any case), taken in file-name order.
//!
//! Timestamps: with [`DatasetConfig::fps`], frame `i` is at `i / fps` seconds. Without it,
//! every file name (without extension) must be a number: seconds when it has a decimal point
//! (`1305031102.175304.png`), nanoseconds when it is an integer of at least 16 digits
//! (`1403636579763555584.png`, EuRoC style); a plain frame number (`000042.png`) says nothing
//! about time, so such a folder needs `fps`. Frames are sorted by time when timed by name.
//! There is no camera, depth or ground truth.

use std::path::{Path, PathBuf};

use super::{parse_error, Dataset, DatasetConfig, DatasetError, DatasetKind, FrameInfo};

/// True when `path` holds at least one image file (see the module documentation).
pub fn has_images(root: &Path) -> bool {
    list_images(root).is_ok_and(|v| !v.is_empty())
}

/// Opens a folder of images (see the module documentation).
pub fn open(root: &Path, config: &DatasetConfig) -> Result<Dataset, DatasetError> {
    let files = list_images(root).map_err(|source| DatasetError::Io {
        path: root.to_path_buf(),
        source,
    })?;
    let mut frames = match config.fps {
        Some(fps) if fps.is_finite() && fps > 0.0 => files
            .into_iter()
            .enumerate()
            .map(|(i, image)| frame(i as f64 / fps, image))
            .collect::<Vec<_>>(),
        Some(fps) => {
            return Err(parse_error(
                root,
                0,
                format!("frame rate {fps} is not a positive number"),
            ))
        }
        None => files
            .into_iter()
            .map(|image| {
                let t = stamp_from_name(&image).ok_or_else(|| {
                    parse_error(
                        &image,
                        0,
                        "the file name is not a timestamp (seconds with a decimal point or \
                         nanoseconds): give a frame rate (`--fps`)",
                    )
                })?;
                Ok(frame(t, image))
            })
            .collect::<Result<Vec<_>, DatasetError>>()?,
    };
    frames.sort_by(|a, b| a.timestamp.total_cmp(&b.timestamp));
    Ok(Dataset {
        kind: DatasetKind::Images,
        root: root.to_path_buf(),
        frames,
        camera: None,
        camera_source: None,
        depth_scale: None,
        ground_truth: None,
        ground_truth_tolerance: config.ground_truth_tolerance,
        camera_in_body: None,
        rig: None,
        bag: Default::default(),
    })
}

fn frame(timestamp: f64, image: PathBuf) -> FrameInfo {
    FrameInfo {
        timestamp,
        image,
        depth: None,
        right: None,
    }
}

/// The image files of `root`, sorted by file name.
fn list_images(root: &Path) -> std::io::Result<Vec<PathBuf>> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(root)?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file() && is_image(p))
        .collect();
    files.sort();
    Ok(files)
}

fn is_image(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| ["png", "jpg", "jpeg"].contains(&e.to_ascii_lowercase().as_str()))
}

/// Seconds from a file name: `s.fraction` as is, an integer of 16 or more digits as
/// nanoseconds; `None` otherwise.
fn stamp_from_name(path: &Path) -> Option<f64> {
    let stem = path.file_stem()?.to_str()?;
    if stem.contains('.') {
        return stem.parse::<f64>().ok().filter(|t| t.is_finite());
    }
    if stem.len() >= 16 && stem.bytes().all(|b| b.is_ascii_digit()) {
        let ns: u64 = stem.parse().ok()?;
        return Some((ns / 1_000_000_000) as f64 + (ns % 1_000_000_000) as f64 * 1e-9);
    }
    None
}

#[cfg(test)]
mod tests {
    use super::stamp_from_name;
    use std::path::Path;

    #[test]
    fn names_are_seconds_or_nanoseconds_never_frame_numbers() {
        let t = |n: &str| stamp_from_name(Path::new(n));
        assert_eq!(t("1305031102.175304.png"), Some(1305031102.175304));
        let ns = t("1403636579763555584.png").expect("ns");
        assert!((ns - 1_403_636_579.0 - 0.763_555_584).abs() < 1e-6);
        assert_eq!(t("000042.png"), None);
        assert_eq!(t("frame_1.png"), None);
    }
}
