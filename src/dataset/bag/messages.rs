//! The ROS 2 messages a bag's frames are made of, decoded from CDR by hand:
//! `sensor_msgs/msg/Image`, `sensor_msgs/msg/CompressedImage` and `sensor_msgs/msg/CameraInfo`
//! (each starting with a `std_msgs/msg/Header`: stamp `int32 sec`, `uint32 nanosec`, then the
//! `frame_id` string).

use image::{DynamicImage, ImageBuffer, Luma, Rgb};
use thiserror::Error;
use vofront_core::camera::{Camera, CameraError, Distortion, KannalaBrandt, Lens, Pinhole};
use vofront_image::Image;

use super::cdr::{CdrError, CdrReader};

/// Schema name of an uncompressed image.
pub const IMAGE: &str = "sensor_msgs/msg/Image";
/// Schema name of a compressed (png, jpeg) image.
pub const COMPRESSED_IMAGE: &str = "sensor_msgs/msg/CompressedImage";
/// The marker of image_transport's `compressedDepth` format in a `CompressedImage`'s
/// `format` (`16UC1; compressedDepth png`, `32FC1; compressedDepth png`).
pub const COMPRESSED_DEPTH: &str = "compressedDepth";
/// Schema name of a camera calibration.
pub const CAMERA_INFO: &str = "sensor_msgs/msg/CameraInfo";

/// Why a message could not be decoded.
#[derive(Debug, Error)]
pub enum MessageError {
    /// The CDR bytes do not hold the message's fields.
    #[error("bad CDR: {0}")]
    Cdr(#[from] CdrError),
    /// An image encoding this reader does not know (or not of the stream's kind).
    #[error("encoding '{encoding}' is not supported for {what} (supported: {supported})")]
    Encoding {
        /// The message's `encoding` (or `format`).
        encoding: String,
        /// Intensity or depth.
        what: &'static str,
        /// The encodings that are.
        supported: &'static str,
    },
    /// `width`, `height` and `step` do not fit the data.
    #[error("{width}x{height} pixels of {bytes_per_pixel} bytes with a row step of {step} bytes need {need} data bytes, the message has {len}")]
    Layout {
        /// Pixels per row.
        width: usize,
        /// Rows.
        height: usize,
        /// Bytes per pixel of the encoding.
        bytes_per_pixel: usize,
        /// Bytes per row as stored.
        step: usize,
        /// Bytes needed.
        need: usize,
        /// Bytes present.
        len: usize,
    },
    /// A compressed image could not be decoded.
    #[error("compressed image ('{format}'): {source}")]
    Compressed {
        /// The message's `format`.
        format: String,
        /// The decoder's error.
        source: Box<image::ImageError>,
    },
    /// A `compressedDepth` payload that is not a 12-byte header and a 16-bit PNG.
    #[error("compressed depth ('{format}'): {reason}")]
    CompressedDepth {
        /// The message's `format`.
        format: String,
        /// What is wrong.
        reason: String,
    },
    /// The message's bytes cannot be read from the bag (its chunk is damaged or cut off).
    #[error("cannot be read from the bag: {0}")]
    Unreadable(String),
    /// The calibration cannot be represented by a vofront camera.
    #[error("camera info: {0}")]
    Calibration(String),
    /// The calibration's numbers make no valid camera.
    #[error("camera info: {0}")]
    Camera(#[from] CameraError),
}

/// The capture time of a message's header, seconds (`sec + nanosec / 1e9`).
pub fn header_stamp(r: &mut CdrReader<'_>) -> Result<f64, CdrError> {
    let sec = r.i32()?;
    let nanosec = r.u32()?;
    r.string()?;
    Ok(f64::from(sec) + f64::from(nanosec) / 1e9)
}

/// The header stamp of a message (any of the three types), seconds.
pub fn stamp(bytes: &[u8]) -> Result<f64, CdrError> {
    header_stamp(&mut CdrReader::new(bytes)?)
}

/// A decoded image message, ready to become an intensity or a depth image.
enum Pixels {
    /// Decoded by the `image` crate (colour, 16-bit, compressed).
    Dynamic(DynamicImage),
    /// 8-bit grey, already in place.
    Grey(Image<u8>),
    /// `32FC1` metres.
    Metres(Image<f32>),
}

/// The encodings of an intensity stream.
const INTENSITY: &str =
    "mono8, mono16, rgb8, bgr8, rgba8, bgra8 (Image); png, jpeg (CompressedImage)";
/// The encodings of a depth stream.
const DEPTH: &str = "16UC1 (mm, or the depth scale), 32FC1 (m), mono16 (Image); 16-bit png, \
     16UC1 and 32FC1 compressedDepth png (CompressedImage)";

/// Decodes an `Image` (`compressed == false`) or `CompressedImage` message to 8-bit grey:
/// colour with the `image` crate's luma weights and 16-bit by its `u16 -> u8` conversion, as
/// for an image file.
pub fn intensity(bytes: &[u8], compressed: bool) -> Result<Image<u8>, MessageError> {
    match pixels(bytes, compressed, false)? {
        Pixels::Grey(g) => Ok(g),
        Pixels::Dynamic(d) => Ok(Image::from_gray_owned(d.into_luma8())),
        Pixels::Metres(_) => Err(encoding_error("32FC1", "an intensity image", INTENSITY)),
    }
}

/// Decodes a depth message to metres: `16UC1`/`mono16` (and 16-bit png) as `raw / scale`,
/// `32FC1` as is with NaN, infinite and negative values as 0 (no depth).
pub fn depth(bytes: &[u8], compressed: bool, scale: f64) -> Result<Image<f32>, MessageError> {
    match pixels(bytes, compressed, true)? {
        Pixels::Metres(m) => Ok(m),
        Pixels::Dynamic(d @ DynamicImage::ImageLuma16(_)) => {
            crate::input::depth_in_metres(&d, scale)
                .ok_or_else(|| encoding_error("16-bit", "a depth image", DEPTH))
        }
        _ => Err(encoding_error("8-bit", "a depth image", DEPTH)),
    }
}

/// The `format` of a `CompressedImage` message.
pub fn compressed_format(bytes: &[u8]) -> Result<String, CdrError> {
    let mut r = CdrReader::new(bytes)?;
    header_stamp(&mut r)?;
    r.string().map(str::to_owned)
}

/// The encoding of an `Image` message (`None` for a `CompressedImage`).
pub fn image_encoding(bytes: &[u8]) -> Result<String, CdrError> {
    let mut r = CdrReader::new(bytes)?;
    header_stamp(&mut r)?;
    r.u32()?;
    r.u32()?;
    r.string().map(str::to_owned)
}

fn encoding_error(encoding: &str, what: &'static str, supported: &'static str) -> MessageError {
    MessageError::Encoding {
        encoding: encoding.to_owned(),
        what,
        supported,
    }
}

fn pixels(bytes: &[u8], compressed: bool, want_depth: bool) -> Result<Pixels, MessageError> {
    let mut r = CdrReader::new(bytes)?;
    header_stamp(&mut r)?;
    if compressed {
        let format = r.string()?.to_owned();
        let data = r.bytes()?;
        if format.contains(COMPRESSED_DEPTH) {
            if !want_depth {
                return Err(encoding_error(&format, "an intensity image", INTENSITY));
            }
            return compressed_depth(&format, data);
        }
        return image::load_from_memory(data)
            .map(Pixels::Dynamic)
            .map_err(|source| MessageError::Compressed {
                format,
                source: Box::new(source),
            });
    }
    let height = r.u32()? as usize;
    let width = r.u32()? as usize;
    let encoding = r.string()?;
    let big_endian = r.u8()? != 0;
    let step = r.u32()? as usize;
    let data = r.bytes()?;
    let bpp = match (encoding, want_depth) {
        ("mono8", false) => 1,
        ("rgb8" | "bgr8", false) => 3,
        ("rgba8" | "bgra8", false) => 4,
        ("mono16", _) | ("16UC1", true) => 2,
        ("32FC1", true) => 4,
        (other, true) => return Err(encoding_error(other, "a depth image", DEPTH)),
        (other, false) => return Err(encoding_error(other, "an intensity image", INTENSITY)),
    };
    let row = width * bpp;
    let need = if height == 0 {
        0
    } else {
        step.saturating_mul(height - 1).saturating_add(row)
    };
    if step < row || data.len() < need || width == 0 || height == 0 {
        return Err(MessageError::Layout {
            width,
            height,
            bytes_per_pixel: bpp,
            step,
            need,
            len: data.len(),
        });
    }
    let rows = || (0..height).map(|y| &data[y * step..y * step + row]);
    let u16s = || {
        rows().flat_map(|r| {
            r.chunks_exact(2).map(move |c| {
                let b = [c[0], c[1]];
                if big_endian {
                    u16::from_be_bytes(b)
                } else {
                    u16::from_le_bytes(b)
                }
            })
        })
    };
    let (w, h) = (width as u32, height as u32);
    let layout = || MessageError::Layout {
        width,
        height,
        bytes_per_pixel: bpp,
        step,
        need,
        len: data.len(),
    };
    Ok(match encoding {
        "mono8" => Pixels::Grey(
            Image::new(width, height, rows().flatten().copied().collect()).map_err(|_| layout())?,
        ),
        "mono16" | "16UC1" => Pixels::Dynamic(DynamicImage::ImageLuma16(
            ImageBuffer::<Luma<u16>, _>::from_raw(w, h, u16s().collect()).ok_or_else(layout)?,
        )),
        "32FC1" => {
            let metres = rows()
                .flat_map(|r| r.chunks_exact(4))
                .map(|c| {
                    let b = [c[0], c[1], c[2], c[3]];
                    let v = if big_endian {
                        f32::from_be_bytes(b)
                    } else {
                        f32::from_le_bytes(b)
                    };
                    if v.is_finite() && v > 0.0 {
                        v
                    } else {
                        0.0
                    }
                })
                .collect();
            Pixels::Metres(Image::new(width, height, metres).map_err(|_| layout())?)
        }
        _ => {
            let bgr = encoding.starts_with("bgr");
            let rgb: Vec<u8> = rows()
                .flat_map(|r| r.chunks_exact(bpp))
                .flat_map(|p| {
                    if bgr {
                        [p[2], p[1], p[0]]
                    } else {
                        [p[0], p[1], p[2]]
                    }
                })
                .collect();
            Pixels::Dynamic(DynamicImage::ImageRgb8(
                ImageBuffer::<Rgb<u8>, _>::from_raw(w, h, rgb).ok_or_else(layout)?,
            ))
        }
    })
}

/// Decodes image_transport's `compressedDepth` payload: a 12-byte header (`int32` format,
/// `float32 depthQuantA`, `float32 depthQuantB`, little-endian) and a 16-bit PNG. For
/// `16UC1` the PNG holds the raw depth units (as an uncompressed `16UC1` image); for `32FC1`
/// the quantised inverse depth `q = A / z + B`, so `z = A / (q - B)` metres (`q = 0`: no depth).
fn compressed_depth(format: &str, data: &[u8]) -> Result<Pixels, MessageError> {
    let bad = |reason: String| MessageError::CompressedDepth {
        format: format.to_owned(),
        reason,
    };
    let (head, png) = data.split_at_checked(12).ok_or_else(|| {
        bad(format!(
            "{} bytes, shorter than the 12-byte header",
            data.len()
        ))
    })?;
    let quant =
        |at: usize| f32::from_le_bytes([head[at], head[at + 1], head[at + 2], head[at + 3]]);
    let decoded =
        image::load_from_memory_with_format(png, image::ImageFormat::Png).map_err(|source| {
            MessageError::Compressed {
                format: format.to_owned(),
                source: Box::new(source),
            }
        })?;
    let DynamicImage::ImageLuma16(q) = decoded else {
        return Err(bad("the PNG is not 16-bit grey".into()));
    };
    if format.starts_with("32FC1") {
        let (a, b) = (quant(4), quant(8));
        let (w, h) = (q.width() as usize, q.height() as usize);
        let metres = q
            .into_raw()
            .into_iter()
            .map(|v| {
                let z = a / (f32::from(v) - b);
                if v != 0 && z.is_finite() && z > 0.0 {
                    z
                } else {
                    0.0
                }
            })
            .collect();
        return Image::new(w, h, metres)
            .map(Pixels::Metres)
            .map_err(|e| bad(e.to_string()));
    }
    Ok(Pixels::Dynamic(DynamicImage::ImageLuma16(q)))
}

/// A decoded `CameraInfo`: image size and the camera it describes.
#[derive(Debug, Clone, PartialEq)]
pub struct CameraInfo {
    /// Header stamp, seconds.
    pub stamp: f64,
    /// Image size `(width, height)`, pixels.
    pub size: (usize, usize),
    /// Intrinsics from `K` and the lens from `distortion_model` and `D`.
    pub camera: Camera,
    /// The projection matrix `P` (3x4, row-major): `P[0][3] = -fx' * baseline` for the right
    /// camera of a rectified stereo pair.
    pub p: [f64; 12],
}

/// Decodes a `CameraInfo`: `K = [fx 0 cx; 0 fy cy; 0 0 1]`; `plumb_bob` (`k1 k2 p1 p2 k3`),
/// `rational_polynomial` (`k1 k2 p1 p2 k3 k4 k5 k6`, only with `k4 = k5 = k6 = 0`: vofront has
/// no rational model) and `equidistant` (`k1..k4`, Kannala-Brandt); an empty `D` is no
/// distortion. Binning and a region of interest are refused.
pub fn camera_info(bytes: &[u8]) -> Result<CameraInfo, MessageError> {
    let mut r = CdrReader::new(bytes)?;
    let stamp = header_stamp(&mut r)?;
    let height = r.u32()? as usize;
    let width = r.u32()? as usize;
    let model = r.string()?.to_owned();
    let d = r.f64_seq()?;
    let k = r.f64_array::<9>()?;
    r.f64_array::<9>()?;
    let p = r.f64_array::<12>()?;
    let (bx, by) = (r.u32()?, r.u32()?);
    let roi = [r.u32()?, r.u32()?, r.u32()?, r.u32()?];
    if bx > 1 || by > 1 || roi[2] != 0 || roi[3] != 0 {
        return Err(MessageError::Calibration(format!(
            "binning {bx}x{by} and region of interest {roi:?} are not supported"
        )));
    }
    let coeff = |i: usize| d.get(i).copied().unwrap_or(0.0);
    let lens: Lens = match (model.as_str(), d.len()) {
        (_, 0) => Lens::default(),
        ("plumb_bob", 4 | 5) => {
            Distortion::from_array([coeff(0), coeff(1), coeff(2), coeff(3), coeff(4)]).into()
        }
        ("rational_polynomial", 5..=8) => {
            if d[5..].iter().any(|&v| v != 0.0) {
                return Err(MessageError::Calibration(format!(
                    "rational_polynomial with k4..k6 = {:?}: vofront's radial-tangential model \
                     has no rational terms (only k4 = k5 = k6 = 0 can be read)",
                    &d[5..]
                )));
            }
            Distortion::from_array([coeff(0), coeff(1), coeff(2), coeff(3), coeff(4)]).into()
        }
        ("equidistant", 4) => KannalaBrandt::new([d[0], d[1], d[2], d[3]])?.into(),
        (model, n) => {
            return Err(MessageError::Calibration(format!(
                "distortion model '{model}' with {n} coefficients is not supported \
                 (plumb_bob: 5, rational_polynomial: 8, equidistant: 4)"
            )))
        }
    };
    let camera = Camera::new(Pinhole::new(k[0], k[4], k[2], k[5])?, lens);
    camera.validate()?;
    Ok(CameraInfo {
        stamp,
        size: (width, height),
        camera,
        p,
    })
}
