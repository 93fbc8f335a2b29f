//! ROS 2 bags (`.mcap`, feature `mcap`) as datasets.
//!
//! [`open`] makes one pass over the bag ([`index`]: through the summary's chunk indexes, or,
//! without a summary, as in a bag cut off mid-file, through the records from the start, so that
//! the frames before the cut are kept, with a note) and keeps only where each message of the
//! chosen topics is; [`Dataset::load`] reads one frame's messages ([`chunks::ChunkReader`]: seek,
//! decompress that chunk, zstd or lz4, a cache of at most [`chunks::CACHE_BYTES`]) and decodes
//! them ([`messages`]: `sensor_msgs/msg/Image` `mono8`, `mono16`, `rgb8`, `bgr8`, `rgba8`,
//! `bgra8` to grey, `16UC1` (depth units, millimetres by default) and `32FC1` (metres) to depth;
//! `CompressedImage` png and jpeg, and `compressedDepth` png as depth).
//!
//! Topics ([`BagTopics`]): the image topic is the one `Image` or `CompressedImage` topic whose
//! first message is not a depth encoding (nor named as the depth or right topic); the depth
//! topic the one `16UC1`/`32FC1` or `compressedDepth` topic (none when there is none); the
//! right topic only when named; the calibration the `CameraInfo` beside the image topic
//! (`/ns/image_raw` -> `/ns/camera_info`), else the only one. Several candidates are an error
//! that lists them ([`BagError::Ambiguous`]).
//!
//! Times are the header stamps (the log time when a stamp is zero or unreadable). Depth and
//! right images are paired with the left ones by stamp, nearest within
//! [`DatasetConfig::depth_tolerance`], each used once; left images without a partner are left
//! out and counted in [`Dataset::notes`]. The camera is the first `CameraInfo` message's
//! (`K`, and `D` by [`messages::camera_info`]); a right topic whose `CameraInfo` has a
//! baseline (`P[0][3] = -fx * b`) makes a stereo rig of the two rectified projections `P`.

pub mod cdr;
pub mod chunks;
pub mod index;
pub mod messages;
pub mod topics;
pub mod write;

use std::path::{Path, PathBuf};
use std::sync::Arc;

use chunks::{ChunkReader, MessageBytes};
use index::Topic;
use nalgebra::Isometry3;
use thiserror::Error;
use vofront_core::camera::{Camera, Pinhole};
use vofront_core::rig::Rig;

use super::{
    mono_rig, CameraSource, Dataset, DatasetConfig, DatasetError, DatasetKind, Frame, FrameInfo,
};
pub use messages::MessageError;
pub use topics::{BagTopics, Stream};

/// Why a bag cannot be opened or one of its messages read.
#[derive(Debug, Error)]
pub enum BagError {
    /// The file cannot be read or does not start as an MCAP file.
    #[error("{path}: not a readable MCAP file: {message}")]
    Read {
        /// The bag.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// Chunks compressed in a way this reader cannot decompress.
    #[error("{path}: chunks compressed with '{compression}', which vofront cannot read (it reads {}); re-compress the bag, e.g. `mcap compress --compression zstd IN.mcap -o OUT.mcap` or `ros2 bag convert` with zstd", chunks::SUPPORTED)]
    Compression {
        /// The bag.
        path: PathBuf,
        /// The compression named by the chunk record.
        compression: String,
    },
    /// No topic of the stream's type.
    #[error("{path}: no {stream} topic (topics of that type: [{}])", topics.join(", "))]
    NoTopic {
        /// The bag.
        path: PathBuf,
        /// The stream.
        stream: Stream,
        /// The topics of the message type (none, or only depth for the image stream).
        topics: Vec<String>,
    },
    /// Several candidate topics and none named.
    #[error("{path}: several {stream} topics: [{}]; choose one with {}", candidates.join(", "), stream.flag())]
    Ambiguous {
        /// The bag.
        path: PathBuf,
        /// The stream.
        stream: Stream,
        /// The candidate topics.
        candidates: Vec<String>,
    },
    /// A named topic is not in the bag with a usable type.
    #[error("{path}: {} {topic}: no such {stream} topic (candidates: [{}])", stream.flag(), candidates.join(", "))]
    NotFound {
        /// The bag.
        path: PathBuf,
        /// The stream.
        stream: Stream,
        /// The topic named.
        topic: String,
        /// The topics of the stream's type.
        candidates: Vec<String>,
    },
    /// A message cannot be decoded.
    #[error("{path}: topic {topic}, message {index}: {source}")]
    Message {
        /// The bag.
        path: PathBuf,
        /// Its topic.
        topic: String,
        /// Zero-based index of the message on its topic.
        index: usize,
        /// What is wrong.
        source: MessageError,
    },
}

impl Topic {
    fn compressed(&self) -> bool {
        self.schema == messages::COMPRESSED_IMAGE
    }
}

/// The messages of the chosen topics behind a bag [`Dataset`]'s frames.
pub struct BagFrames {
    path: PathBuf,
    reader: ChunkReader,
    indexed: bool,
    image: Topic,
    right: Option<Topic>,
    depth: Option<Topic>,
    /// Per frame: message positions in `image`, `right`, `depth`.
    slots: Vec<(usize, Option<usize>, Option<usize>)>,
    notes: Vec<String>,
}

impl std::fmt::Debug for BagFrames {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("BagFrames")
            .field("path", &self.path)
            .field("image", &self.image.name)
            .field("right", &self.right.as_ref().map(|t| &t.name))
            .field("depth", &self.depth.as_ref().map(|t| &t.name))
            .field("frames", &self.slots.len())
            .finish()
    }
}

impl BagFrames {
    /// What opening the bag left out or met (a cut, unpaired frames).
    pub fn notes(&self) -> &[String] {
        &self.notes
    }

    /// True when the messages were found through the summary's chunk indexes, false when by
    /// reading the records from the start (no summary: a bag cut off, or written without one).
    pub fn indexed(&self) -> bool {
        self.indexed
    }

    /// The decompressed chunks held in the cache now and their bytes (at most
    /// [`chunks::CACHE_BYTES`] unless one chunk alone is larger).
    pub fn cached(&self) -> (usize, usize) {
        self.reader.cached()
    }

    fn error(&self, topic: &Topic, at: usize, source: MessageError) -> DatasetError {
        BagError::Message {
            path: self.path.clone(),
            topic: topic.name.clone(),
            index: topic.messages[at].index,
            source,
        }
        .into()
    }

    /// The bytes of message `at` of `topic`.
    fn bytes(&self, topic: &Topic, at: usize) -> Result<MessageBytes, DatasetError> {
        self.reader
            .message(&topic.messages[at].place)
            .map_err(|e| self.error(topic, at, MessageError::Unreadable(e)))
    }

    /// Frame `index` (in range): grey image, depth in metres (`raw / depth_scale` for 16-bit),
    /// and the right image when `stereo`.
    pub(crate) fn load(
        &self,
        index: usize,
        timestamp: f64,
        depth_scale: f64,
        stereo: bool,
    ) -> Result<Frame, DatasetError> {
        let (i, r, d) = self.slots[index];
        let image = &self.image;
        let left = messages::intensity(self.bytes(image, i)?.bytes(), image.compressed())
            .map_err(|e| self.error(image, i, e))?;
        let depth = match (&self.depth, d) {
            (Some(t), Some(d)) => Some(
                messages::depth(self.bytes(t, d)?.bytes(), t.compressed(), depth_scale)
                    .map_err(|e| self.error(t, d, e))?,
            ),
            _ => None,
        };
        let frame = Frame::new(timestamp, left, depth)
            .map_err(|source| DatasetError::Frame { index, source })?;
        match (&self.right, r, stereo) {
            (Some(t), Some(r), true) => {
                let right = messages::intensity(self.bytes(t, r)?.bytes(), t.compressed())
                    .map_err(|e| self.error(t, r, e))?;
                frame
                    .with_right(right)
                    .map_err(|source| DatasetError::Frame { index, source })
            }
            (_, _, true) => Err(DatasetError::NoRightImage { index }),
            _ => Ok(frame),
        }
    }
}

/// True when a topic's first message is depth: an `Image` of encoding `16UC1` or `32FC1`, or
/// a `CompressedImage` of a `compressedDepth` format.
fn is_depth(topic: &Topic) -> bool {
    if topic.compressed() {
        return messages::compressed_format(&topic.first)
            .is_ok_and(|f| f.contains(messages::COMPRESSED_DEPTH));
    }
    topic.schema == messages::IMAGE
        && messages::image_encoding(&topic.first).is_ok_and(|e| e == "16UC1" || e == "32FC1")
}

/// The camera of a calibration topic's first message.
fn calibration(path: &Path, topic: &Topic) -> Result<Option<messages::CameraInfo>, BagError> {
    messages::camera_info(&topic.first)
        .map(Some)
        .map_err(|source| BagError::Message {
            path: path.to_path_buf(),
            topic: topic.name.clone(),
            index: 0,
            source,
        })
}

/// Opens the bag at `path` (see the module documentation).
pub fn open(
    path: &Path,
    config: &DatasetConfig,
    choice: &BagTopics,
) -> Result<Dataset, DatasetError> {
    let index::Scan {
        chunks,
        topics: mut all,
        mut notes,
        indexed,
    } = index::scan(path)?;
    let file = std::fs::File::open(path).map_err(|e| BagError::Read {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    let mut names: Vec<&Topic> = all.values().collect();
    names.sort_by(|a, b| a.name.cmp(&b.name));
    let of = |f: &dyn Fn(&Topic) -> bool| -> Vec<String> {
        names
            .iter()
            .filter(|t| f(t))
            .map(|t| t.name.clone())
            .collect()
    };
    let images = of(&|t| t.schema != messages::CAMERA_INFO);
    let named = |t: &Topic, n: &Option<String>| n.as_deref() == Some(t.name.as_str());
    let intensity = of(&|t| {
        t.schema != messages::CAMERA_INFO
            && !is_depth(t)
            && !named(t, &choice.depth)
            && !named(t, &choice.right)
    });
    let depths = of(&|t| is_depth(t));
    let infos = of(&|t| t.schema == messages::CAMERA_INFO);
    let image = topics::pick(
        path,
        Stream::Image,
        choice.image.as_deref(),
        &intensity,
        &images,
        None,
        true,
    )?
    .unwrap_or_default();
    let right = match &choice.right {
        Some(_) => topics::pick(
            path,
            Stream::Right,
            choice.right.as_deref(),
            &[],
            &images,
            None,
            true,
        )?,
        None => None,
    };
    let depth = topics::pick(
        path,
        Stream::Depth,
        choice.depth.as_deref(),
        &depths,
        &images,
        None,
        false,
    )?;
    let sibling = topics::sibling_camera_info(&image);
    let info = topics::pick(
        path,
        Stream::CameraInfo,
        choice.camera_info.as_deref(),
        &infos,
        &infos,
        sibling.as_deref(),
        false,
    )?;
    let left_info = match &info {
        Some(t) => calibration(path, &all[t])?,
        None => None,
    };
    let right_info = match right.as_deref().and_then(topics::sibling_camera_info) {
        Some(t) if all.contains_key(&t) => calibration(path, &all[&t])?,
        _ => None,
    };
    let mut take = |name: &Option<String>| {
        name.as_ref().and_then(|n| all.remove(n)).map(|mut t| {
            t.messages.sort_by(|a, b| a.stamp.total_cmp(&b.stamp));
            t
        })
    };
    let image = take(&Some(image)).ok_or_else(|| BagError::NoTopic {
        path: path.to_path_buf(),
        stream: Stream::Image,
        topics: images.clone(),
    })?;
    let (right, depth) = (take(&right), take(&depth));
    let stamps = |t: &Topic| t.messages.iter().map(|m| m.stamp).collect::<Vec<_>>();
    let left_stamps = stamps(&image);
    let pair = |t: &Option<Topic>, notes: &mut Vec<String>| match t {
        Some(t) => {
            let m = topics::match_stamps(&left_stamps, &stamps(t), config.depth_tolerance);
            let missing = m.iter().filter(|m| m.is_none()).count();
            if missing > 0 {
                notes.push(format!(
                    "{} of {} images on {} have no message on {} within {} s: left out",
                    missing,
                    m.len(),
                    image.name,
                    t.name,
                    config.depth_tolerance
                ));
            }
            m.into_iter().map(Some).collect()
        }
        None => vec![None; left_stamps.len()],
    };
    let right_of: Vec<Option<Option<usize>>> = pair(&right, &mut notes);
    let depth_of: Vec<Option<Option<usize>>> = pair(&depth, &mut notes);
    let mut slots = Vec::new();
    let mut frames = Vec::new();
    for (i, (r, d)) in right_of.into_iter().zip(depth_of).enumerate() {
        if r == Some(None) || d == Some(None) {
            continue;
        }
        let (r, d) = (r.flatten(), d.flatten());
        slots.push((i, r, d));
        frames.push(FrameInfo {
            timestamp: left_stamps[i],
            image: path.to_path_buf(),
            depth: d.map(|_| path.to_path_buf()),
            right: r.map(|_| path.to_path_buf()),
        });
    }
    let camera = left_info.as_ref().map(|c| c.camera);
    let rig = match (&left_info, &right_info) {
        (Some(l), Some(r)) if r.p[3] != 0.0 => {
            let projection =
                |p: &[f64; 12]| Pinhole::new(p[0], p[5], p[2], p[6]).map(Camera::pinhole);
            let to_dataset = |source| DatasetError::Rig {
                path: path.to_path_buf(),
                source,
            };
            let bag_error = |source: vofront_core::camera::CameraError| {
                DatasetError::from(BagError::Message {
                    path: path.to_path_buf(),
                    topic: info.clone().unwrap_or_default(),
                    index: 0,
                    source: source.into(),
                })
            };
            let (lc, rc) = (
                projection(&l.p).map_err(bag_error)?,
                projection(&r.p).map_err(bag_error)?,
            );
            let baseline = -r.p[3] / r.p[0];
            Some(
                Rig::stereo(
                    lc,
                    Isometry3::identity(),
                    rc,
                    Isometry3::translation(baseline, 0.0, 0.0),
                )
                .map_err(to_dataset)?,
            )
        }
        _ => mono_rig(camera, None, path)?,
    };
    let camera = rig.as_ref().map(|r| *r.left()).or(camera);
    Ok(Dataset {
        kind: DatasetKind::Bag,
        root: path.to_path_buf(),
        frames,
        camera,
        camera_source: info.map(CameraSource::Topic),
        depth_scale: depth.as_ref().map(|_| 1000.0),
        ground_truth: None,
        ground_truth_tolerance: config.ground_truth_tolerance,
        camera_in_body: None,
        rig,
        bag: Some(Arc::new(BagFrames {
            path: path.to_path_buf(),
            reader: ChunkReader::new(file, chunks),
            indexed,
            image,
            right,
            depth,
            slots,
            notes,
        })),
    })
}
