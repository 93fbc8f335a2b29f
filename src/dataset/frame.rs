//! A loaded frame: capture time, grey image, optional depth map and right (stereo) image.

use thiserror::Error;
use vofront_image::Image;

/// One loaded frame: a finite capture time, an 8-bit grey image ([`Image<u8>`], the left one
/// of a stereo pair) and, optionally, a metric depth map ([`Image<f32>`], metres) and a right
/// (stereo) image of the same size (checked by [`Frame::new`] and [`Frame::with_right`], so
/// every tracker can index them with the image's pixel coordinates).
///
/// ```
/// use vofront::dataset::{Frame, FrameError};
/// use vofront::image::Image;
/// let image = Image::filled(4, 3, 90u8);
/// let frame = Frame::new(0.5, image.clone(), Some(Image::filled(4, 3, 1.5f32))).unwrap();
/// assert_eq!((frame.timestamp(), frame.image().size()), (0.5, (4, 3)));
/// assert_eq!(frame.depth().unwrap().at(3, 2), 1.5);
///
/// let small = Image::filled(2, 2, 0.0f32);
/// assert!(matches!(Frame::new(0.5, image.clone(), Some(small)), Err(FrameError::DepthSize { .. })));
/// assert!(matches!(Frame::new(f64::NAN, image.clone(), None), Err(FrameError::Timestamp(_))));
///
/// let stereo = Frame::new(0.5, image.clone(), None).unwrap().with_right(image.clone()).unwrap();
/// assert_eq!(stereo.right().unwrap().size(), (4, 3));
/// let narrow = Image::filled(3, 3, 0u8);
/// assert!(matches!(Frame::new(0.5, image, None).unwrap().with_right(narrow), Err(FrameError::RightSize { .. })));
/// ```
#[derive(Debug, Clone)]
pub struct Frame {
    timestamp: f64,
    image: Image<u8>,
    depth: Option<Image<f32>>,
    right: Option<Image<u8>>,
}

/// Why [`Frame::new`] refused its parts.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum FrameError {
    /// The capture time is NaN or infinite.
    #[error("timestamp {0} is not a finite number of seconds")]
    Timestamp(f64),
    /// The depth map's size differs from the image's (`(width, height)`, pixels).
    #[error("depth is {depth:?}, image is {image:?}")]
    DepthSize {
        /// Image size.
        image: (usize, usize),
        /// Depth map size.
        depth: (usize, usize),
    },
    /// The right image's size differs from the (left) image's (`(width, height)`, pixels).
    #[error("right image is {right:?}, left image is {image:?}")]
    RightSize {
        /// Left image size.
        image: (usize, usize),
        /// Right image size.
        right: (usize, usize),
    },
}

impl Frame {
    /// A frame at `timestamp` (seconds, finite) with its grey image and an optional metric
    /// depth map (metres, `0.0` = no depth) of the image's size.
    pub fn new(
        timestamp: f64,
        image: Image<u8>,
        depth: Option<Image<f32>>,
    ) -> Result<Self, FrameError> {
        if !timestamp.is_finite() {
            return Err(FrameError::Timestamp(timestamp));
        }
        if let Some(d) = &depth {
            if d.size() != image.size() {
                return Err(FrameError::DepthSize {
                    image: image.size(),
                    depth: d.size(),
                });
            }
        }
        Ok(Self {
            timestamp,
            image,
            depth,
            right: None,
        })
    }

    /// The same frame with the right image of a stereo pair, which must have the (left)
    /// image's size.
    pub fn with_right(self, right: Image<u8>) -> Result<Self, FrameError> {
        if right.size() != self.image.size() {
            return Err(FrameError::RightSize {
                image: self.image.size(),
                right: right.size(),
            });
        }
        Ok(Self {
            right: Some(right),
            ..self
        })
    }

    /// Capture time, seconds.
    pub fn timestamp(&self) -> f64 {
        self.timestamp
    }

    /// The image, 8-bit grey.
    pub fn image(&self) -> &Image<u8> {
        &self.image
    }

    /// Metric depth (metres, 0 = invalid), the image's size; `None` without depth.
    pub fn depth(&self) -> Option<&Image<f32>> {
        self.depth.as_ref()
    }

    /// The right image of a stereo pair, 8-bit grey, the image's size; `None` for a
    /// monocular frame.
    pub fn right(&self) -> Option<&Image<u8>> {
        self.right.as_ref()
    }

    /// The same frame without its depth map (a monocular view of an RGB-D frame).
    pub fn without_depth(self) -> Self {
        Self {
            depth: None,
            ..self
        }
    }

    /// The same frame at another capture time (seconds, finite).
    pub fn with_timestamp(self, timestamp: f64) -> Result<Self, FrameError> {
        if !timestamp.is_finite() {
            return Err(FrameError::Timestamp(timestamp));
        }
        Ok(Self { timestamp, ..self })
    }

    /// `(timestamp, image, depth)`, moved out (the right image, if any, is dropped).
    pub fn into_parts(self) -> (f64, Image<u8>, Option<Image<f32>>) {
        (self.timestamp, self.image, self.depth)
    }
}
