//! Reading the files a user gives: images, depth maps and correspondence lists, with errors
//! that name the file.

use std::path::{Path, PathBuf};

use image::GrayImage;
use thiserror::Error;

/// A metric depth map: metres per pixel, 0 where unknown (the image crate's float image).
pub use vofront_image::GrayF32 as DepthMap;

/// A file could not be used.
#[derive(Debug, Error)]
pub enum InputError {
    /// The file does not exist or cannot be read.
    #[error("cannot read {path}: {source}")]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The file is not an image in a supported format (PNG, JPEG).
    #[error("{path}: not a supported image ({reason})")]
    Decode {
        /// The file.
        path: PathBuf,
        /// What the decoder said.
        reason: String,
    },
    /// A depth map that is not single-channel 16-bit or 8-bit.
    #[error("{path}: depth must be a single-channel 16-bit (or 8-bit) image")]
    DepthFormat {
        /// The file.
        path: PathBuf,
    },
    /// A line of a text file that cannot be parsed.
    #[error("{path}:{line}: {reason}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        reason: String,
    },
}

fn open(path: &Path) -> Result<image::DynamicImage, InputError> {
    let bytes = std::fs::read(path).map_err(|source| InputError::Read {
        path: path.into(),
        source,
    })?;
    image::load_from_memory(&bytes).map_err(|e| InputError::Decode {
        path: path.into(),
        reason: e.to_string(),
    })
}

/// Loads any supported image as 8-bit grey (colour is converted with Rec. 601 luma).
pub fn load_gray(path: &Path) -> Result<GrayImage, InputError> {
    Ok(open(path)?.into_luma8())
}

/// Loads a depth PNG and divides the stored values by `scale` (depth units per metre) into
/// metres, see [`depth_in_metres`].
pub fn load_depth(path: &Path, scale: f64) -> Result<DepthMap, InputError> {
    depth_in_metres(&open(path)?, scale)
        .ok_or_else(|| InputError::DepthFormat { path: path.into() })
}

/// A decoded depth image in metres: `z = raw / scale` with `scale` the depth units per metre;
/// 0 stays 0 (no depth). `None` unless the image is single-channel 8-bit or 16-bit.
///
/// Both bit depths are read as stored: an 8-bit value `v` is `v / scale` metres, never
/// widened to 16 bits first (which would multiply it by 257). The scale is the caller's: TUM
/// stores 5000 units per metre, a 16-bit millimetre map is 1000, an 8-bit map is whatever its
/// writer chose (e.g. 25 for 4 cm steps up to 10.2 m).
pub fn depth_in_metres(image: &image::DynamicImage, scale: f64) -> Option<DepthMap> {
    let metres = |raw: &mut dyn Iterator<Item = f64>| -> Vec<f32> {
        raw.map(|d| (d / scale) as f32).collect()
    };
    let values = match image {
        image::DynamicImage::ImageLuma16(d) => metres(&mut d.iter().map(|&v| f64::from(v))),
        image::DynamicImage::ImageLuma8(d) => metres(&mut d.iter().map(|&v| f64::from(v))),
        _ => return None,
    };
    Some(
        DepthMap::from_raw(image.width(), image.height(), values)
            .expect("one value per decoded pixel"),
    )
}

/// Pixel correspondences `(x1, y1) <-> (x2, y2)`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Correspondences {
    /// Points in image 1, pixels.
    pub x1: Vec<nalgebra::Vector2<f64>>,
    /// Matching points in image 2, pixels.
    pub x2: Vec<nalgebra::Vector2<f64>>,
}

/// Reads a CSV of correspondences: columns `x1,y1,x2,y2`, further columns ignored, an optional
/// header line (any first line whose first field is not a number), `#` comments skipped.
pub fn load_correspondences(path: &Path) -> Result<Correspondences, InputError> {
    let text = std::fs::read_to_string(path).map_err(|source| InputError::Read {
        path: path.into(),
        source,
    })?;
    let mut out = Correspondences::default();
    let mut header_allowed = true;
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let fields: Vec<&str> = line
            .split([',', ' ', '\t', ';'])
            .filter(|f| !f.is_empty())
            .collect();
        let numbers: Result<Vec<f64>, _> =
            fields.iter().take(4).map(|f| f.parse::<f64>()).collect();
        match numbers {
            Ok(v) if v.len() == 4 => {
                out.x1.push(nalgebra::Vector2::new(v[0], v[1]));
                out.x2.push(nalgebra::Vector2::new(v[2], v[3]));
            }
            _ if header_allowed && fields.first().is_some_and(|f| f.parse::<f64>().is_err()) => {}
            _ => {
                return Err(InputError::Parse {
                    path: path.into(),
                    line: i + 1,
                    reason: "expected four numbers x1,y1,x2,y2".into(),
                })
            }
        }
        header_allowed = false;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::{ImageBuffer, Luma};

    #[test]
    fn depth_is_divided_by_the_scale_as_stored_in_8_and_16_bits() {
        let dir = std::env::temp_dir().join(format!("vofront-input-depth-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let (p8, p16) = (dir.join("d8.png"), dir.join("d16.png"));
        GrayImage::from_fn(3, 2, |x, _| Luma([x as u8 * 50]))
            .save(&p8)
            .unwrap();
        ImageBuffer::<Luma<u16>, Vec<u16>>::from_fn(3, 2, |x, _| Luma([x as u16 * 5000]))
            .save(&p16)
            .unwrap();
        // 8-bit 50 at 25 units per metre is 2 m (not 50 * 257 / 25).
        let d8 = load_depth(&p8, 25.0).unwrap();
        assert_eq!(d8.as_raw(), &[0.0, 2.0, 4.0, 0.0, 2.0, 4.0]);
        let d16 = load_depth(&p16, 5000.0).unwrap();
        assert_eq!(d16.as_raw(), &[0.0, 1.0, 2.0, 0.0, 1.0, 2.0]);
        image::RgbImage::new(2, 2)
            .save(dir.join("rgb.png"))
            .unwrap();
        assert!(matches!(
            load_depth(&dir.join("rgb.png"), 1.0),
            Err(InputError::DepthFormat { .. })
        ));
        std::fs::remove_dir_all(&dir).ok();
    }
}
