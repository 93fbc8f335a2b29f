//! Writing ROS 2 bags: the CDR of `sensor_msgs/msg/Image`, `CompressedImage` and `CameraInfo`
//! ([`image_message`], [`compressed_image_message`], [`camera_info_message`]) and of
//! `geometry_msgs/msg/PoseStamped` ([`pose_stamped_message`]); [`BagWriter`], an MCAP file of
//! such messages (one channel per topic), as rosbag2 writes them; [`PoseBagSink`], a
//! trajectory streamed into a bag for Foxglove (`vofront odometry --out traj.mcap`).

use std::collections::BTreeMap;
use std::io::{self, Seek, Write};

use nalgebra::Isometry3;
use vofront_core::camera::{Camera, Lens};

use super::cdr::CdrWriter;
use crate::odometry::run::FrameRecord;
use crate::odometry::sink::FrameSink;

/// Schema name of a stamped pose.
pub const POSE_STAMPED: &str = "geometry_msgs/msg/PoseStamped";

/// The `ros2msg` definitions the header types need (after a message's own fields).
const HEADER_DEFINITION: &str = "
================================================================================
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id
================================================================================
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec
";

/// The `ros2msg` schema text of a message type this module writes (the type's fields, then
/// each type it uses), which viewers such as Foxglove need to decode the CDR; empty for
/// another name.
pub fn schema_definition(name: &str) -> String {
    use super::messages::{CAMERA_INFO, COMPRESSED_IMAGE, IMAGE};
    let own = match name {
        IMAGE => "std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\nuint8 is_bigendian\nuint32 step\nuint8[] data\n",
        COMPRESSED_IMAGE => "std_msgs/Header header\nstring format\nuint8[] data\n",
        CAMERA_INFO => "std_msgs/Header header\nuint32 height\nuint32 width\nstring distortion_model\nfloat64[] d\nfloat64[9] k\nfloat64[9] r\nfloat64[12] p\nuint32 binning_x\nuint32 binning_y\nsensor_msgs/RegionOfInterest roi\n",
        POSE_STAMPED => "std_msgs/Header header\ngeometry_msgs/Pose pose\n",
        _ => return String::new(),
    };
    let used = match name {
        CAMERA_INFO => "================================================================================\nMSG: sensor_msgs/RegionOfInterest\nuint32 x_offset\nuint32 y_offset\nuint32 height\nuint32 width\nbool do_rectify\n",
        POSE_STAMPED => "================================================================================\nMSG: geometry_msgs/Pose\nPoint position\nQuaternion orientation\n================================================================================\nMSG: geometry_msgs/Point\nfloat64 x\nfloat64 y\nfloat64 z\n================================================================================\nMSG: geometry_msgs/Quaternion\nfloat64 x\nfloat64 y\nfloat64 z\nfloat64 w\n",
        _ => "",
    };
    format!("{own}{HEADER_DEFINITION}{used}")
}

/// A `std_msgs/msg/Header` at `stamp_ns` (nanoseconds) in frame `frame_id`.
fn header_in(w: &mut CdrWriter, stamp_ns: u64, frame_id: &str) {
    w.i32((stamp_ns / 1_000_000_000) as i32)
        .u32((stamp_ns % 1_000_000_000) as u32)
        .string(frame_id);
}

/// A `std_msgs/msg/Header` at `stamp_ns` (nanoseconds) with `frame_id` `camera`.
fn header(w: &mut CdrWriter, stamp_ns: u64) {
    header_in(w, stamp_ns, "camera");
}

/// A `geometry_msgs/msg/PoseStamped` of `pose` in `frame_id`: position `x y z`, then the
/// orientation quaternion `x y z w`.
pub fn pose_stamped_message(stamp_ns: u64, frame_id: &str, pose: &Isometry3<f64>) -> Vec<u8> {
    let t = pose.translation.vector;
    let q = pose.rotation.quaternion().coords;
    let mut c = CdrWriter::new();
    header_in(&mut c, stamp_ns, frame_id);
    c.f64s(&[t.x, t.y, t.z, q.x, q.y, q.z, q.w], false);
    c.finish()
}

/// The geometry of an [`image_message`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ImageLayout<'a> {
    /// Pixels per row.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// `encoding` (`mono8`, `rgb8`, `16UC1`, ...).
    pub encoding: &'a str,
    /// Multi-byte pixels (and the CDR) in big-endian order.
    pub big_endian: bool,
    /// Bytes per stored row (at least `width` times the bytes per pixel; the rest is padding).
    pub step: usize,
}

/// A `sensor_msgs/msg/Image` of `rows` (`height` rows of packed pixels, each padded to
/// `step` bytes with `0xEE`).
pub fn image_message(stamp_ns: u64, layout: ImageLayout<'_>, rows: &[u8]) -> Vec<u8> {
    let row = rows.len() / layout.height.max(1);
    let mut data = Vec::with_capacity(layout.step * layout.height);
    for r in rows.chunks(row.max(1)) {
        data.extend_from_slice(r);
        data.resize(data.len() + layout.step.saturating_sub(row), 0xEE);
    }
    let mut c = if layout.big_endian {
        CdrWriter::big_endian()
    } else {
        CdrWriter::new()
    };
    header(&mut c, stamp_ns);
    c.u32(layout.height as u32)
        .u32(layout.width as u32)
        .string(layout.encoding)
        .u8(u8::from(layout.big_endian))
        .u32(layout.step as u32)
        .bytes(&data);
    c.finish()
}

/// A `sensor_msgs/msg/CompressedImage` (`format` `png` or `jpeg`, `data` the file's bytes).
pub fn compressed_image_message(stamp_ns: u64, format: &str, data: &[u8]) -> Vec<u8> {
    let mut c = CdrWriter::new();
    header(&mut c, stamp_ns);
    c.string(format).bytes(data);
    c.finish()
}

/// A `sensor_msgs/msg/CameraInfo` with distortion model `model` and coefficients `d`,
/// `K = [fx 0 cx; 0 fy cy; 0 0 1]` from `k = [fx, fy, cx, cy]`, identity `R` and
/// `P = [fx 0 cx tx; 0 fy cy 0; 0 0 1 0]` (`tx = -fx * baseline` for a right camera).
pub fn camera_info_message(
    stamp_ns: u64,
    (width, height): (usize, usize),
    model: &str,
    d: &[f64],
    k: [f64; 4],
    tx: f64,
) -> Vec<u8> {
    let [fx, fy, cx, cy] = k;
    let mut c = CdrWriter::new();
    header(&mut c, stamp_ns);
    c.u32(height as u32)
        .u32(width as u32)
        .string(model)
        .f64s(d, true)
        .f64s(&[fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0], false)
        .f64s(&[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0], false)
        .f64s(
            &[fx, 0.0, cx, tx, 0.0, fy, cy, 0.0, 0.0, 0.0, 1.0, 0.0],
            false,
        );
    // binning_x, binning_y, roi {x_offset, y_offset, height, width, do_rectify}
    c.u32(0).u32(0).u32(0).u32(0).u32(0).u32(0).u8(0);
    c.finish()
}

/// The `CameraInfo` of `camera` for images of `size`: `plumb_bob` or `equidistant`.
pub fn camera_message(stamp_ns: u64, size: (usize, usize), camera: &Camera) -> Vec<u8> {
    let p = camera.pinhole;
    let k = [p.fx, p.fy, p.cx, p.cy];
    let model = match camera.distortion {
        Lens::RadialTangential(_) => "plumb_bob",
        Lens::KannalaBrandt(_) => "equidistant",
    };
    let d = camera.distortion.coefficients();
    camera_info_message(stamp_ns, size, model, &d, k, 0.0)
}

/// An MCAP file of CDR messages, one channel (and schema) per topic.
pub struct BagWriter<W: Write + Seek> {
    writer: mcap::Writer<W>,
    channels: BTreeMap<String, u16>,
    sequence: u32,
}

impl<W: Write + Seek> BagWriter<W> {
    /// A bag written to `w`: zstd chunks when `chunked`, else one record after another.
    pub fn new(w: W, chunked: bool) -> Result<Self, mcap::McapError> {
        let writer = mcap::WriteOptions::new()
            .profile("ros2")
            .use_chunks(chunked)
            .create(w)?;
        Ok(Self {
            writer,
            channels: BTreeMap::new(),
            sequence: 0,
        })
    }

    /// Writes `data` (a CDR message of schema `schema`, e.g.
    /// [`messages::IMAGE`](super::messages::IMAGE), whose [`schema_definition`] goes with the
    /// channel) on `topic` at log time `stamp_ns`.
    pub fn write(
        &mut self,
        topic: &str,
        schema: &str,
        stamp_ns: u64,
        data: &[u8],
    ) -> Result<(), mcap::McapError> {
        let id = match self.channels.get(topic) {
            Some(&id) => id,
            None => {
                let text = schema_definition(schema);
                let schema = self.writer.add_schema(schema, "ros2msg", text.as_bytes())?;
                let id = self
                    .writer
                    .add_channel(schema, topic, "cdr", &BTreeMap::new())?;
                self.channels.insert(topic.to_owned(), id);
                id
            }
        };
        let header = mcap::records::MessageHeader {
            channel_id: id,
            sequence: self.sequence,
            log_time: stamp_ns,
            publish_time: stamp_ns,
        };
        self.sequence += 1;
        self.writer.write_to_known_channel(&header, data)
    }

    /// Writes the summary and returns the output.
    pub fn finish(mut self) -> Result<W, mcap::McapError> {
        self.writer.finish()?;
        Ok(self.writer.into_inner())
    }
}

/// Streams each tracked frame's camera pose `T_wc` ([`FrameRecord::trajectory_pose`]) as a
/// `geometry_msgs/msg/PoseStamped` in frame `world` on the topic `/vofront/pose` of a bag
/// without chunks, flushed per frame (a run cut short leaves a bag a streaming reader reads to
/// its last pose); [`PoseBagSink::finish`] writes the summary.
pub struct PoseBagSink<W: Write + Seek> {
    bag: BagWriter<W>,
}

impl<W: Write + Seek> PoseBagSink<W> {
    /// The topic of the poses.
    pub const TOPIC: &'static str = "/vofront/pose";

    /// A sink writing into `w`.
    pub fn new(w: W) -> io::Result<Self> {
        Ok(Self {
            bag: BagWriter::new(w, false).map_err(io::Error::other)?,
        })
    }

    /// Writes the summary and returns the output.
    pub fn finish(self) -> io::Result<W> {
        self.bag.finish().map_err(io::Error::other)
    }
}

impl<W: Write + Seek> FrameSink for PoseBagSink<W> {
    fn frame(&mut self, record: &FrameRecord) -> io::Result<()> {
        if let Some(pose) = record.trajectory_pose() {
            let ns = (record.timestamp.max(0.0) * 1e9).round() as u64;
            let msg = pose_stamped_message(ns, "world", &pose);
            self.bag
                .write(Self::TOPIC, POSE_STAMPED, ns, &msg)
                .and_then(|()| self.bag.writer.flush())
                .map_err(io::Error::other)?;
        }
        Ok(())
    }
}
