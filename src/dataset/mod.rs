//! Image-sequence datasets: TUM RGB-D, KITTI odometry and EuRoC MAV folders.
//!
//! [`Dataset::open`] detects the format from the folder layout, reads the frame lists,
//! calibration and optional ground truth, and leaves the images on disk;
//! [`Dataset::load`] reads one frame on demand. A missing or corrupt image is an `Err` for
//! that frame index only ([`Dataset::iter`] yields it and moves on).
//!
//! | format | detected by | camera | right camera (stereo rig) | depth | ground truth |
//! |---|---|---|---|---|---|
//! | [`tum`] | `rgb.txt` | freiburg1/2/3 preset from the folder name or list headers | none (mono rig) | `depth.txt`, 16-bit PNG / 5000 | `groundtruth.txt`, camera `T_wc` |
//! | [`kitti`] | `image_0/` + `times.txt` | `calib.txt` line `P0` | `image_1/` (same file names), `calib.txt` line `P1`, baseline `-P1[3] / P1[0]` | none | `poses.txt` or `../../poses/<seq>.txt`, camera `T_wc` |
//! | [`euroc`] | `mav0/cam0/data.csv` | `mav0/cam0/sensor.yaml` | `mav0/cam1/` (`data.csv`, `sensor.yaml` with its `T_BS`), paired by timestamp | none | `mav0/state_groundtruth_estimate0/data.csv`, **body (IMU) pose** `T_wb` (camera: `T_wb * camera_in_body`) |
//! | [`images`] | `.png`/`.jpg` files | none | none | none | none |
//!
//! [`Dataset::camera`] is the camera the dataset describes and [`Dataset::camera_source`]
//! says where it was found; for TUM it is the freiburg1/2/3 preset named by the folder name
//! or by the `# file:` header of its lists ([`tum::tum_preset_for`]).
//!
//! [`Dataset::rig`] holds the cameras with their poses in the body frame
//! ([`vofront_core::rig::Rig`]): stereo when the folder has a right camera (KITTI `image_1/`,
//! EuRoC `cam1/`; body = left camera for KITTI, the IMU for EuRoC), else mono (the camera at
//! the body origin, EuRoC: at its `T_BS`). The right images are listed in
//! [`FrameInfo::right`] and read only by [`Dataset::load_stereo`]: [`Dataset::load`] (the
//! monocular and RGB-D path) never touches them. Rectify a stereo rig once with
//! [`vofront_core::rectify::StereoRectification`].
//!
//! ```
//! use image::{GrayImage, Luma};
//! use vofront::dataset::{Dataset, DatasetKind};
//! let dir = std::env::temp_dir().join(format!("vofront-doc-dataset-{}", std::process::id()));
//! std::fs::create_dir_all(dir.join("rgb")).unwrap();
//! std::fs::write(dir.join("rgb.txt"), "# timestamp filename\n1.0 rgb/a.png\n1.1 rgb/b.png\n").unwrap();
//! GrayImage::from_pixel(4, 3, Luma([9])).save(dir.join("rgb/a.png")).unwrap();
//!
//! let data = Dataset::open(&dir).unwrap();
//! assert_eq!(data.kind, DatasetKind::Tum);
//! assert_eq!(data.frames.len(), 2);
//! assert_eq!(data.load(0).unwrap().image().size(), (4, 3));
//! assert!(data.load(1).is_err()); // rgb/b.png is missing: that frame fails, the run goes on
//! std::fs::remove_dir_all(&dir).unwrap();
//! ```

#[cfg(feature = "mcap")]
pub mod bag;
pub mod euroc;
mod frame;
pub mod images;
pub mod kitti;
pub mod tum;

use std::io;
use std::path::{Path, PathBuf};

use image::DynamicImage;
use nalgebra::Isometry3;
use thiserror::Error;
use vofront_core::camera::{Camera, CameraError};
use vofront_core::rig::{Rig, RigError};
use vofront_image::Image;

use crate::trajectory::{Trajectory, TrajectoryError};

pub use frame::{Frame, FrameError};

/// The former name of a metric depth map, now [`Image<f32>`] (metres, `0.0` where the sensor
/// gave no depth), kept for users' code.
#[deprecated(note = "use vofront_image::Image<f32>")]
pub type DepthImage = Image<f32>;

/// Errors of dataset opening and frame loading.
#[derive(Debug, Error)]
pub enum DatasetError {
    /// The folder does not exist or is empty.
    #[error("{0}: folder is empty or does not exist")]
    Empty(PathBuf),
    /// The folder layout matches no supported format.
    #[error("{0}: not a TUM RGB-D (rgb.txt), KITTI (image_0/, times.txt), EuRoC (mav0/cam0/data.csv) or image folder")]
    Unrecognised(PathBuf),
    /// The format needs a calibration file that is absent.
    #[error("{path}: calibration file missing")]
    MissingCalibration {
        /// The expected calibration file.
        path: PathBuf,
    },
    /// A file could not be read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        source: io::Error,
    },
    /// A line of a list, calibration or ground-truth file could not be parsed.
    #[error("{path}:{line}: {message}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// One-based line number (0 when the file as a whole lacks an entry).
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// A ground-truth file could not be read (see [`TrajectoryError`]).
    #[error(transparent)]
    Trajectory(#[from] TrajectoryError),
    /// The calibration gives an invalid camera.
    #[error("{path}: {source}")]
    Camera {
        /// The calibration file.
        path: PathBuf,
        /// Why the camera is invalid.
        source: CameraError,
    },
    /// The dataset lists no frame.
    #[error("{0}: the dataset lists no frame")]
    NoFrames(PathBuf),
    /// The image folder and the timestamp list hold different numbers of frames (KITTI).
    #[error("{images_dir}: {images} images, but {times_file} lists {times} timestamps")]
    FrameCount {
        /// The image folder.
        images_dir: PathBuf,
        /// Number of images in it.
        images: usize,
        /// The timestamp list.
        times_file: PathBuf,
        /// Number of timestamps in it.
        times: usize,
    },
    /// The right image of a left image is missing (KITTI `image_1/`).
    #[error("{path}: right image missing (its left image is {left})")]
    MissingRightImage {
        /// The expected right image.
        path: PathBuf,
        /// The left image it pairs with.
        left: PathBuf,
    },
    /// [`Dataset::load_stereo`] on a frame without a right image.
    #[error("frame {index}: the dataset lists no right image for it")]
    NoRightImage {
        /// Frame index.
        index: usize,
    },
    /// The calibration gives an invalid camera rig (e.g. a zero baseline).
    #[error("{path}: {source}")]
    Rig {
        /// The calibration file that completes the rig (KITTI `calib.txt`, EuRoC
        /// `cam1/sensor.yaml`; the camera's file or folder for a mono rig).
        path: PathBuf,
        /// Why the rig is invalid.
        source: RigError,
    },
    /// A frame index past the end of the frame list.
    #[error("frame {index} requested, the dataset has {len}")]
    FrameIndex {
        /// Requested index.
        index: usize,
        /// Number of frames.
        len: usize,
    },
    /// A frame image or depth map is missing or cannot be decoded.
    #[error("frame {index}: {path}: {source}")]
    Image {
        /// Frame index.
        index: usize,
        /// The image file.
        path: PathBuf,
        /// The decoder error.
        source: image::ImageError,
    },
    /// A listed frame's parts do not make a [`Frame`] (a non-finite timestamp, a right
    /// image of another size).
    #[error("frame {index}: {source}")]
    Frame {
        /// Frame index.
        index: usize,
        /// What is wrong.
        source: FrameError,
    },
    /// A ROS 2 bag cannot be opened or a message of a frame cannot be decoded.
    #[cfg(feature = "mcap")]
    #[error(transparent)]
    Bag(Box<bag::BagError>),
    /// A depth map is not a single-channel 16-bit or 8-bit image or does not match the image size.
    #[error("frame {index}: {path}: {message}")]
    BadDepth {
        /// Frame index.
        index: usize,
        /// The depth file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
}

#[cfg(feature = "mcap")]
impl From<bag::BagError> for DatasetError {
    fn from(e: bag::BagError) -> Self {
        Self::Bag(Box::new(e))
    }
}

/// Which dataset format a folder holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DatasetKind {
    /// TUM RGB-D benchmark sequence.
    Tum,
    /// KITTI odometry sequence (left grey camera `image_0`).
    Kitti,
    /// EuRoC MAV sequence (camera `cam0`).
    Euroc,
    /// A plain folder of images ([`images`]).
    Images,
    /// A ROS 2 bag (`.mcap`, feature `mcap`).
    Bag,
}

/// Where [`Dataset::camera`] came from.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum CameraSource {
    /// A calibration file of the dataset: KITTI `calib.txt` (`P0`), EuRoC `sensor.yaml`.
    CalibrationFile(PathBuf),
    /// The TUM camera (`freiburg1`, `freiburg2`, `freiburg3`) named by the folder name.
    FolderName(String),
    /// The TUM camera named in a file of the folder (the `# file: 'rgbd_dataset_freiburgN_...'`
    /// header of `rgb.txt`, `depth.txt` or `groundtruth.txt`).
    FileHeader(PathBuf),
    /// The first message of a ROS 2 bag's `sensor_msgs/msg/CameraInfo` topic.
    Topic(String),
}

impl std::fmt::Display for CameraSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            CameraSource::CalibrationFile(p) => write!(f, "calibration file {}", p.display()),
            CameraSource::FolderName(name) => write!(f, "TUM {name} preset (from the folder name)"),
            CameraSource::FileHeader(p) => write!(f, "TUM preset named in {}", p.display()),
            CameraSource::Topic(t) => write!(f, "camera info topic {t}"),
        }
    }
}

/// One frame as listed by the dataset (nothing loaded yet).
#[derive(Debug, Clone, PartialEq)]
pub struct FrameInfo {
    /// Capture time, seconds.
    pub timestamp: f64,
    /// The intensity (or colour) image file.
    pub image: PathBuf,
    /// The associated depth image file, if any.
    pub depth: Option<PathBuf>,
    /// The right image of a stereo pair (same size as `image`), if any; read by
    /// [`Dataset::load_stereo`] only.
    pub right: Option<PathBuf>,
}

/// Options of [`Dataset::open_with`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DatasetConfig {
    /// Maximum |t_rgb - t_depth| (s) for a TUM depth map to be paired with an image.
    pub depth_tolerance: f64,
    /// Maximum |t_frame - t_gt| (s) for [`Dataset::ground_truth_at`].
    pub ground_truth_tolerance: f64,
    /// Frame rate (Hz) of a plain image folder: frame `i` at `i / fps` s. `None`: times from
    /// the file names ([`images`]).
    pub fps: Option<f64>,
}

impl Default for DatasetConfig {
    /// 0.02 s for both tolerances, the default of the TUM benchmark's `associate.py`; image
    /// folders timed by their file names.
    fn default() -> Self {
        Self {
            depth_tolerance: 0.02,
            ground_truth_tolerance: 0.02,
            fps: None,
        }
    }
}

/// An opened dataset folder: frame list, calibration and ground truth.
#[derive(Debug, Clone)]
pub struct Dataset {
    /// The detected format.
    pub kind: DatasetKind,
    /// The folder that was opened.
    pub root: PathBuf,
    /// Frames in capture order.
    pub frames: Vec<FrameInfo>,
    /// The camera the dataset describes: its calibration file (KITTI, EuRoC) or the TUM
    /// preset its folder name or file headers name; `None` when it says nothing.
    pub camera: Option<Camera>,
    /// Where [`Dataset::camera`] came from (`None` exactly when `camera` is `None`).
    pub camera_source: Option<CameraSource>,
    /// Depth-image units per metre (TUM: 5000), `None` without depth.
    pub depth_scale: Option<f64>,
    /// Ground truth as published: camera `T_wc` for TUM and KITTI, **body (IMU) `T_wb`** for
    /// EuRoC (the camera pose is `T_wb * T_bs` with `T_BS` from `cam0/sensor.yaml`).
    pub ground_truth: Option<Trajectory>,
    /// Maximum |t_frame - t_gt| (s) used by [`Dataset::ground_truth_at`].
    pub ground_truth_tolerance: f64,
    /// EuRoC only: `T_bc`, the camera pose in the body (IMU) frame (`T_BS` of
    /// `cam0/sensor.yaml`, maps camera points into the body frame), so that the camera
    /// ground truth is `T_wc = T_wb * T_bc`. `None` for TUM and KITTI.
    pub camera_in_body: Option<Isometry3<f64>>,
    /// The camera rig (see the module documentation): stereo with a right camera (KITTI
    /// `image_1/` + `P1`, EuRoC `cam1/`), else mono around [`Dataset::camera`]; `None`
    /// exactly when `camera` is `None`. Its left camera is [`Dataset::camera`].
    pub rig: Option<Rig>,
    /// A ROS 2 bag's messages behind the frames (feature `mcap`); nothing for a folder.
    #[cfg_attr(not(feature = "mcap"), allow(dead_code))]
    pub(crate) bag: BagHandle,
}

/// The messages of a bag dataset ([`bag::BagFrames`]), none for a folder.
#[cfg(feature = "mcap")]
pub(crate) type BagHandle = Option<std::sync::Arc<bag::BagFrames>>;
/// Without the `mcap` feature there are no bags.
#[cfg(not(feature = "mcap"))]
pub(crate) type BagHandle = ();

impl Dataset {
    /// Opens `path` with [`DatasetConfig::default`], detecting the format.
    pub fn open(path: impl AsRef<Path>) -> Result<Self, DatasetError> {
        Self::open_with(path, &DatasetConfig::default())
    }

    /// Opens `path`, detecting the format from its layout (see the module documentation).
    pub fn open_with(path: impl AsRef<Path>, config: &DatasetConfig) -> Result<Self, DatasetError> {
        let root = path.as_ref();
        #[cfg(feature = "mcap")]
        if root.is_file()
            && root
                .extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("mcap"))
        {
            return Self::open_bag(root, config, &bag::BagTopics::default());
        }
        let mut entries = std::fs::read_dir(root).map_err(|_| DatasetError::Empty(root.into()))?;
        if entries.next().is_none() {
            return Err(DatasetError::Empty(root.into()));
        }
        let dataset = if root.join("rgb.txt").is_file() {
            tum::open(root, config)?
        } else if root.join("image_0").is_dir() && root.join("times.txt").is_file() {
            kitti::open(root, config)?
        } else if root.join("mav0/cam0/data.csv").is_file() {
            euroc::open(root, config)?
        } else if images::has_images(root) {
            images::open(root, config)?
        } else {
            return Err(DatasetError::Unrecognised(root.into()));
        };
        if dataset.frames.is_empty() {
            return Err(DatasetError::NoFrames(root.into()));
        }
        Ok(dataset)
    }

    /// Opens a ROS 2 bag (`.mcap`) with the topics of `topics` (see [`bag`]).
    #[cfg(feature = "mcap")]
    pub fn open_bag(
        path: impl AsRef<Path>,
        config: &DatasetConfig,
        topics: &bag::BagTopics,
    ) -> Result<Self, DatasetError> {
        let path = path.as_ref();
        let dataset = bag::open(path, config, topics)?;
        if dataset.frames.is_empty() {
            return Err(DatasetError::NoFrames(path.into()));
        }
        Ok(dataset)
    }

    /// The bag behind a ROS 2 bag dataset (feature `mcap`): how it was read
    /// ([`bag::BagFrames::indexed`]) and its chunk cache; `None` for a folder.
    #[cfg(feature = "mcap")]
    pub fn bag_frames(&self) -> Option<&bag::BagFrames> {
        self.bag.as_deref()
    }

    /// What opening the dataset met and worked around (a bag cut off early, images without
    /// a depth or right partner left out); empty for a folder.
    pub fn notes(&self) -> Vec<String> {
        #[cfg(feature = "mcap")]
        if let Some(bag) = &self.bag {
            return bag.notes().to_vec();
        }
        Vec::new()
    }

    /// Number of frames.
    pub fn len(&self) -> usize {
        self.frames.len()
    }

    /// True when there is no frame (never the case for an opened dataset).
    pub fn is_empty(&self) -> bool {
        self.frames.is_empty()
    }

    /// Loads frame `index`: the image as 8-bit grey (colour converted with the `image`
    /// crate's luma weights; the decoded buffer moves into the [`Image<u8>`], no copy) and, if
    /// listed, the depth map as metres (`raw / depth_scale`). A listed right image is not read
    /// (see [`Dataset::load_stereo`]).
    pub fn load(&self, index: usize) -> Result<Frame, DatasetError> {
        let info = self.info(index)?;
        #[cfg(feature = "mcap")]
        if let Some(bag) = &self.bag {
            return bag.load(
                index,
                info.timestamp,
                self.depth_scale.unwrap_or(1000.0),
                false,
            );
        }
        let image = Image::from_gray_owned(open_image(index, &info.image)?.into_luma8());
        let depth = match &info.depth {
            Some(path) => Some(self.load_depth(index, path)?),
            None => None,
        };
        Frame::new(info.timestamp, image, depth).map_err(|source| match (source, &info.depth) {
            (size @ FrameError::DepthSize { .. }, Some(path)) => DatasetError::BadDepth {
                index,
                path: path.clone(),
                message: size.to_string(),
            },
            (source, _) => DatasetError::Frame { index, source },
        })
    }

    /// Loads frame `index` as [`Dataset::load`] plus its right image (8-bit grey, the left
    /// image's size): [`DatasetError::NoRightImage`] when the frame has none listed,
    /// [`DatasetError::Image`] when it cannot be read, [`DatasetError::Frame`] when its size
    /// differs.
    pub fn load_stereo(&self, index: usize) -> Result<Frame, DatasetError> {
        #[cfg(feature = "mcap")]
        if let Some(bag) = &self.bag {
            let info = self.info(index)?;
            return bag.load(
                index,
                info.timestamp,
                self.depth_scale.unwrap_or(1000.0),
                true,
            );
        }
        let path = self
            .info(index)?
            .right
            .as_ref()
            .ok_or(DatasetError::NoRightImage { index })?;
        let right = Image::from_gray_owned(open_image(index, path)?.into_luma8());
        self.load(index)?
            .with_right(right)
            .map_err(|source| DatasetError::Frame { index, source })
    }

    /// The listing of frame `index`.
    fn info(&self, index: usize) -> Result<&FrameInfo, DatasetError> {
        self.frames.get(index).ok_or(DatasetError::FrameIndex {
            index,
            len: self.frames.len(),
        })
    }

    /// All frames in order as `(index, result)`; a failed frame yields its `Err` and the
    /// iteration continues.
    pub fn iter(&self) -> impl Iterator<Item = (usize, Result<Frame, DatasetError>)> + '_ {
        (0..self.frames.len()).map(|i| (i, self.load(i)))
    }

    /// The ground-truth pose nearest in time to frame `index`, if within
    /// [`Dataset::ground_truth_tolerance`] (frame of the pose: see [`Dataset::ground_truth`]).
    pub fn ground_truth_at(&self, index: usize) -> Option<Isometry3<f64>> {
        let t = self.frames.get(index)?.timestamp;
        let gt = self.ground_truth.as_ref()?;
        gt.nearest(t, self.ground_truth_tolerance).map(|(_, p)| *p)
    }

    /// The depth map of frame `index` in metres (its size is checked by [`Frame::new`]).
    fn load_depth(&self, index: usize, path: &Path) -> Result<Image<f32>, DatasetError> {
        let raw = open_image(index, path)?;
        crate::input::depth_in_metres(&raw, self.depth_scale.unwrap_or(1.0)).ok_or_else(|| {
            DatasetError::BadDepth {
                index,
                path: path.to_path_buf(),
                message: format!("expected 16-bit or 8-bit grey, got {:?}", raw.color()),
            }
        })
    }
}

fn open_image(index: usize, path: &Path) -> Result<DynamicImage, DatasetError> {
    image::open(path).map_err(|source| DatasetError::Image {
        index,
        path: path.to_path_buf(),
        source,
    })
}

/// Reads a text file of the dataset, mapping the error to [`DatasetError::Io`].
fn read_text(path: &Path) -> Result<String, DatasetError> {
    std::fs::read_to_string(path).map_err(|source| DatasetError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// The records of a comma-separated file with `#` comment lines and no header, fields
/// trimmed, each with its one-based line number (read with the `csv` crate).
fn csv_records(path: &Path) -> Result<Vec<(usize, csv::StringRecord)>, DatasetError> {
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(false)
        .comment(Some(b'#'))
        .flexible(true)
        .trim(csv::Trim::All)
        .from_path(path)
        .map_err(|e| csv_error(path, e))?;
    reader
        .records()
        .map(|r| {
            let record = r.map_err(|e| csv_error(path, e))?;
            let line = record.position().map_or(0, |p| p.line() as usize);
            Ok((line, record))
        })
        .filter(|r| !matches!(r, Ok((_, rec)) if rec.iter().all(str::is_empty)))
        .collect()
}

fn csv_error(path: &Path, e: csv::Error) -> DatasetError {
    let line = e.position().map_or(0, |p| p.line() as usize);
    match e.into_kind() {
        csv::ErrorKind::Io(source) => DatasetError::Io {
            path: path.to_path_buf(),
            source,
        },
        other => parse_error(path, line, format!("{other:?}")),
    }
}

/// A [`DatasetError::Parse`] for `path` at one-based `line`.
fn parse_error(path: &Path, line: usize, message: impl Into<String>) -> DatasetError {
    DatasetError::Parse {
        path: path.to_path_buf(),
        line,
        message: message.into(),
    }
}

/// The rig of a one-camera dataset: `camera` at `t_bs` in the body frame (identity when
/// unknown); `None` without a camera. `path`: the calibration file named by an error.
fn mono_rig(
    camera: Option<Camera>,
    t_bs: Option<Isometry3<f64>>,
    path: &Path,
) -> Result<Option<Rig>, DatasetError> {
    camera
        .map(|c| Rig::mono_in_body(c, t_bs.unwrap_or_else(Isometry3::identity)))
        .transpose()
        .map_err(|source| DatasetError::Rig {
            path: path.to_path_buf(),
            source,
        })
}
