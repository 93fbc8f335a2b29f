//! Reading the files a user gives: images, depth maps and correspondence lists, with errors
//! that name the file.

use std::path::{Path, PathBuf};

use thiserror::Error;
use vofront_image::Image;

/// The former name of a metric depth map, now [`Image<f32>`] (metres per pixel, 0 where
/// unknown), kept for users' code.
#[deprecated(note = "use vofront_image::Image<f32>")]
pub type DepthMap = Image<f32>;

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

/// Loads any supported image as 8-bit grey (colour is converted with Rec. 601 luma); the
/// decoded buffer moves into the [`Image<u8>`] without a copy.
pub fn load_gray(path: &Path) -> Result<Image<u8>, InputError> {
    Ok(Image::from_gray_owned(open(path)?.into_luma8()))
}

/// Loads a depth PNG and divides the stored values by `scale` (depth units per metre) into
/// metres, see [`depth_in_metres`].
pub fn load_depth(path: &Path, scale: f64) -> Result<Image<f32>, InputError> {
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
pub fn depth_in_metres(image: &image::DynamicImage, scale: f64) -> Option<Image<f32>> {
    let metres = |raw: &mut dyn Iterator<Item = f64>| -> Vec<f32> {
        raw.map(|d| (d / scale) as f32).collect()
    };
    let values = match image {
        image::DynamicImage::ImageLuma16(d) => metres(&mut d.iter().map(|&v| f64::from(v))),
        image::DynamicImage::ImageLuma8(d) => metres(&mut d.iter().map(|&v| f64::from(v))),
        _ => return None,
    };
    Some(
        Image::new(image.width() as usize, image.height() as usize, values)
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

/// One correspondence row, `x1,y1,x2,y2` in pixels (read by serde from the first four
/// fields of a CSV record).
#[derive(Debug, serde::Deserialize)]
struct CorrespondenceRow {
    x1: f64,
    y1: f64,
    x2: f64,
    y2: f64,
}

/// The field separator of a correspondence file: the first of `,` `;` and tab that occurs on
/// its first data line, else a space (runs of spaces are one separator).
fn sniff_delimiter(text: &str) -> u8 {
    let first = text
        .lines()
        .map(str::trim)
        .find(|l| !l.is_empty() && !l.starts_with('#'))
        .unwrap_or("");
    [b',', b';', b'\t']
        .into_iter()
        .find(|&d| first.as_bytes().contains(&d))
        .unwrap_or(b' ')
}

/// Reads a CSV of correspondences with the `csv` crate: columns `x1,y1,x2,y2` (pixels),
/// further columns ignored, separated by commas, semicolons, tabs or spaces (the one the first
/// data line uses), an optional header line (a first line whose first field is not a number),
/// `#` comment lines and blank lines skipped.
///
/// ```
/// let path = std::env::temp_dir().join(format!("vofront-doc-matches-{}.csv", std::process::id()));
/// std::fs::write(&path, "x1,y1,x2,y2,score\n10,20,12.5,21,0.9\n# a comment\n30,40,31,42,0.8\n").unwrap();
/// let c = vofront::input::load_correspondences(&path).unwrap();
/// assert_eq!(c.x1.len(), 2);
/// assert_eq!((c.x2[0].x, c.x2[1].y), (12.5, 42.0));
/// std::fs::write(&path, "10,20,12.5\n").unwrap();
/// let err = vofront::input::load_correspondences(&path).unwrap_err().to_string();
/// assert!(err.ends_with(":1: expected four numbers x1,y1,x2,y2, got 3 fields"), "{err}");
/// std::fs::remove_file(&path).unwrap();
/// ```
pub fn load_correspondences(path: &Path) -> Result<Correspondences, InputError> {
    let text = std::fs::read_to_string(path).map_err(|source| InputError::Read {
        path: path.into(),
        source,
    })?;
    let parse_error = |line: usize, reason: String| InputError::Parse {
        path: path.into(),
        line,
        reason,
    };
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(false)
        .delimiter(sniff_delimiter(&text))
        .comment(Some(b'#'))
        .flexible(true)
        .trim(csv::Trim::All)
        .from_reader(text.as_bytes());
    let mut out = Correspondences::default();
    let mut header_allowed = true;
    for record in reader.records() {
        let record = record.map_err(|e| {
            let line = e.position().map_or(0, |p| p.line() as usize);
            parse_error(line, e.to_string())
        })?;
        let line = record.position().map_or(0, |p| p.line() as usize);
        // Runs of spaces give empty fields between them: they are one separator.
        let fields: csv::StringRecord = record.iter().filter(|f| !f.is_empty()).collect();
        let Some(first) = fields.get(0) else {
            continue;
        };
        if std::mem::take(&mut header_allowed) && first.parse::<f64>().is_err() {
            continue;
        }
        if fields.len() < 4 {
            return Err(parse_error(
                line,
                format!(
                    "expected four numbers x1,y1,x2,y2, got {} fields",
                    fields.len()
                ),
            ));
        }
        let four: csv::StringRecord = fields.iter().take(4).collect();
        let row: CorrespondenceRow = four.deserialize(None).map_err(|e| {
            let detail = match e.kind() {
                csv::ErrorKind::Deserialize { err, .. } => match err.field() {
                    Some(k) => format!("column {}: {}", k + 1, err.kind()),
                    None => err.kind().to_string(),
                },
                other => format!("{other:?}"),
            };
            parse_error(
                line,
                format!("expected four numbers x1,y1,x2,y2 ({detail})"),
            )
        })?;
        out.x1.push(nalgebra::Vector2::new(row.x1, row.y1));
        out.x2.push(nalgebra::Vector2::new(row.x2, row.y2));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::{GrayImage, ImageBuffer, Luma};

    /// Writes `text` to a temporary file and reads it as correspondences.
    fn read_matches(name: &str, text: &str) -> Result<Correspondences, InputError> {
        let path =
            std::env::temp_dir().join(format!("vofront-input-{name}-{}.csv", std::process::id()));
        std::fs::write(&path, text).unwrap();
        let out = load_correspondences(&path);
        std::fs::remove_file(&path).ok();
        out
    }

    #[test]
    fn correspondences_accept_every_separator_header_comments_and_extra_columns() {
        let want = |c: &Correspondences| {
            assert_eq!(
                c.x1,
                vec![
                    nalgebra::Vector2::new(1.0, 2.0),
                    nalgebra::Vector2::new(5.0, 6.0)
                ]
            );
            assert_eq!(
                c.x2,
                vec![
                    nalgebra::Vector2::new(3.0, 4.5),
                    nalgebra::Vector2::new(7.0, -8.0)
                ]
            );
        };
        want(&read_matches("comma", "x1,y1,x2,y2\n1,2,3,4.5\n5, 6, 7, -8\n").unwrap());
        want(&read_matches("semi", "# from a tool\n1;2;3;4.5;0.9\n\n5;6;7;-8;0.1\n").unwrap());
        want(&read_matches("tab", "u1\tv1\tu2\tv2\n1\t2\t3\t4.5\r\n5\t6\t7\t-8\r\n").unwrap());
        want(&read_matches("space", "1   2 3  4.5\n5 6 7 -8 extra\n").unwrap());
        assert_eq!(
            read_matches("empty", "x1,y1,x2,y2\n").unwrap(),
            Correspondences::default()
        );
    }

    #[test]
    fn bad_correspondence_lines_name_the_line_and_the_column() {
        let err = |name: &str, text: &str| read_matches(name, text).unwrap_err().to_string();
        // Only the first line may be a header.
        let e = err("late-header", "1,2,3,4\nx1,y1,x2,y2\n");
        assert!(
            e.ends_with(":2: expected four numbers x1,y1,x2,y2 (column 1: invalid float literal)"),
            "{e}"
        );
        let e = err("short", "x1,y1,x2,y2\n1,2,3,4\n1,2\n");
        assert!(
            e.ends_with(":3: expected four numbers x1,y1,x2,y2, got 2 fields"),
            "{e}"
        );
        let e = err("word", "1,2,3,4\n5,6,seven,8\n");
        assert!(
            e.ends_with(":2: expected four numbers x1,y1,x2,y2 (column 3: invalid float literal)"),
            "{e}"
        );
        assert!(matches!(
            load_correspondences(Path::new("/nonexistent/matches.csv")),
            Err(InputError::Read { .. })
        ));
    }

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
        assert_eq!(d8.data(), &[0.0, 2.0, 4.0, 0.0, 2.0, 4.0]);
        let d16 = load_depth(&p16, 5000.0).unwrap();
        assert_eq!(d16.data(), &[0.0, 1.0, 2.0, 0.0, 1.0, 2.0]);
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
