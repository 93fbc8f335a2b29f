//! ROS 2 bags read per frame: through the summary's chunk indexes (seek, decompress one chunk,
//! a bounded cache), by a linear read when the summary is cut off, lz4 chunks (hand-written
//! MCAP files, as `ros2 bag record` writes them with lz4), an unknown compression as a typed
//! error, and image_transport's `compressedDepth` depth images.

use std::fs;
use std::io::{Cursor, Write};
use std::path::PathBuf;

use image::{DynamicImage, GrayImage, ImageBuffer, ImageFormat, Luma};
use vofront::dataset::bag::chunks::CACHE_BYTES;
use vofront::dataset::bag::write::{
    compressed_image_message, image_message, BagWriter, ImageLayout,
};
use vofront::dataset::bag::{messages, BagError, MessageError};
use vofront::dataset::{Dataset, DatasetError};
use vofront::image::Image;

/// A path under the system temp dir for this test, removed on drop.
struct TempFile(PathBuf);

impl TempFile {
    fn new(name: &str) -> Self {
        Self(std::env::temp_dir().join(format!("vofront-bagstream-{}-{name}", std::process::id())))
    }
}

impl Drop for TempFile {
    fn drop(&mut self) {
        fs::remove_file(&self.0).ok();
    }
}

/// Grey hashed noise (incompressible, so that a bag of it has several chunks of its size).
fn pattern(w: u32, h: u32, seed: u32) -> GrayImage {
    GrayImage::from_fn(w, h, |x, y| {
        let mut v = x.wrapping_mul(0x9E37_79B1)
            ^ y.wrapping_mul(0x85EB_CA77)
            ^ seed.wrapping_mul(0xC2B2_AE3D);
        v ^= v >> 15;
        v = v.wrapping_mul(0x2C1B_3C6D);
        v ^= v >> 12;
        Luma([(v >> 24) as u8])
    })
}

fn mono8(ns: u64, img: &GrayImage) -> Vec<u8> {
    let (w, h) = (img.width() as usize, img.height() as usize);
    let layout = ImageLayout {
        width: w,
        height: h,
        encoding: "mono8",
        big_endian: false,
        step: w,
    };
    image_message(ns, layout, img.as_raw())
}

fn expect_bag_error(result: Result<Dataset, DatasetError>) -> BagError {
    match result {
        Err(DatasetError::Bag(e)) => *e,
        other => panic!("expected a bag error, got {other:?}"),
    }
}

#[test]
fn chunked_bag_reads_through_the_index_and_a_cut_one_linearly() {
    // 30 frames of 320x240 mono8 (77 kB each): several zstd chunks of about 1 MB.
    let n = 30u32;
    let mut w = BagWriter::new(Cursor::new(Vec::new()), true).unwrap();
    for i in 0..n {
        let ns = 1_000_000_000 + u64::from(i) * 100_000_000;
        w.write(
            "/cam/image_raw",
            messages::IMAGE,
            ns,
            &mono8(ns, &pattern(320, 240, i)),
        )
        .unwrap();
    }
    let bytes = w.finish().unwrap().into_inner();
    let file = TempFile::new("chunked.mcap");
    fs::write(&file.0, &bytes).unwrap();

    let data = Dataset::open(&file.0).unwrap();
    let bag = data.bag_frames().expect("a bag dataset");
    assert!(bag.indexed(), "a complete bag is read through its summary");
    assert_eq!(data.len(), n as usize);
    assert!(data.notes().is_empty(), "{:?}", data.notes());
    // Out of order first (the last frame, then the first), then every frame in order.
    for i in [n as usize - 1, 0].into_iter().chain(0..n as usize) {
        let frame = data.load(i).unwrap();
        assert_eq!(
            frame.image(),
            &Image::from_gray_owned(pattern(320, 240, i as u32)),
            "frame {i}"
        );
        assert!((frame.timestamp() - (1.0 + 0.1 * i as f64)).abs() < 1e-9);
        let (chunks, held) = bag.cached();
        assert!(
            chunks >= 1 && held <= CACHE_BYTES,
            "{chunks} chunks, {held} bytes"
        );
    }
    // 2.3 MB of frames in chunks of about 1 MB, all read and (under the bound) cached.
    assert!(bag.cached().0 >= 2, "{:?}", bag.cached());

    // Cut at 60%: no summary, the records are read from the start; every frame of a whole
    // chunk before the cut is there, exactly.
    fs::write(&file.0, &bytes[..bytes.len() * 6 / 10]).unwrap();
    let cut = Dataset::open(&file.0).unwrap();
    assert!(!cut.bag_frames().unwrap().indexed());
    assert!((1..n as usize).contains(&cut.len()), "{} frames", cut.len());
    assert!(
        cut.notes().iter().any(|m| m.contains("ends early")),
        "{:?}",
        cut.notes()
    );
    for i in 0..cut.len() {
        assert_eq!(
            cut.load(i).unwrap().image(),
            &Image::from_gray_owned(pattern(320, 240, i as u32))
        );
    }
}

/// An MCAP record: opcode, body length (u64 LE), body.
fn record(out: &mut Vec<u8>, op: u8, body: &[u8]) {
    out.push(op);
    out.extend((body.len() as u64).to_le_bytes());
    out.extend(body);
}

fn string(b: &mut Vec<u8>, s: &str) {
    b.extend((s.len() as u32).to_le_bytes());
    b.extend(s.as_bytes());
}

/// A hand-written MCAP file: one chunk, compressed with `compression` (`"lz4"`: the LZ4 frame
/// format; any other name is stored uncompressed under that name), holding the schema, the
/// channel `/cam/image_raw` and `frames` mono8 messages; with a summary (schema, channel,
/// chunk index) when `summary`.
fn hand_written_bag(compression: &str, frames: &[GrayImage], summary: bool) -> Vec<u8> {
    let mut schema = Vec::new();
    schema.extend(1u16.to_le_bytes());
    string(&mut schema, messages::IMAGE);
    string(&mut schema, "ros2msg");
    string(&mut schema, "");
    let mut channel = Vec::new();
    channel.extend(1u16.to_le_bytes());
    channel.extend(1u16.to_le_bytes());
    string(&mut channel, "/cam/image_raw");
    string(&mut channel, "cdr");
    channel.extend(0u32.to_le_bytes());
    let mut records = Vec::new();
    record(&mut records, 0x03, &schema);
    record(&mut records, 0x04, &channel);
    for (i, img) in frames.iter().enumerate() {
        let ns = 1_000 + i as u64 * 50_000_000;
        let mut m = Vec::new();
        m.extend(1u16.to_le_bytes());
        m.extend((i as u32).to_le_bytes());
        m.extend(ns.to_le_bytes());
        m.extend(ns.to_le_bytes());
        m.extend(mono8(ns, img));
        record(&mut records, 0x05, &m);
    }
    let data = if compression == "lz4" {
        let mut enc = lz4_flex::frame::FrameEncoder::new(Vec::new());
        enc.write_all(&records).unwrap();
        enc.finish().unwrap()
    } else {
        records.clone()
    };
    let mut chunk = Vec::new();
    chunk.extend(1_000u64.to_le_bytes());
    chunk.extend((1_000 + frames.len() as u64 * 50_000_000).to_le_bytes());
    chunk.extend((records.len() as u64).to_le_bytes());
    chunk.extend(0u32.to_le_bytes());
    string(&mut chunk, compression);
    chunk.extend((data.len() as u64).to_le_bytes());
    chunk.extend(&data);

    let mut out = b"\x89MCAP0\r\n".to_vec();
    let mut header = Vec::new();
    string(&mut header, "ros2");
    string(&mut header, "hand");
    record(&mut out, 0x01, &header);
    let chunk_at = out.len() as u64;
    record(&mut out, 0x06, &chunk);
    let chunk_len = out.len() as u64 - chunk_at;
    record(&mut out, 0x0F, &0u32.to_le_bytes());
    let summary_at = out.len() as u64;
    if summary {
        record(&mut out, 0x03, &schema);
        record(&mut out, 0x04, &channel);
        let mut index = Vec::new();
        index.extend(&chunk[..16]);
        index.extend(chunk_at.to_le_bytes());
        index.extend(chunk_len.to_le_bytes());
        index.extend(10u32.to_le_bytes());
        index.extend(1u16.to_le_bytes());
        index.extend(0u64.to_le_bytes());
        index.extend(0u64.to_le_bytes());
        string(&mut index, compression);
        index.extend((data.len() as u64).to_le_bytes());
        index.extend((records.len() as u64).to_le_bytes());
        record(&mut out, 0x08, &index);
    }
    let mut footer = Vec::new();
    footer.extend((if summary { summary_at } else { 0 }).to_le_bytes());
    footer.extend(0u64.to_le_bytes());
    footer.extend(0u32.to_le_bytes());
    record(&mut out, 0x02, &footer);
    out.extend(b"\x89MCAP0\r\n");
    out
}

#[test]
fn lz4_chunks_read_with_and_without_a_summary() {
    let frames: Vec<GrayImage> = (0..5).map(|i| pattern(64, 48, i)).collect();
    let file = TempFile::new("lz4.mcap");
    for summary in [true, false] {
        fs::write(&file.0, hand_written_bag("lz4", &frames, summary)).unwrap();
        let data = Dataset::open(&file.0).unwrap();
        assert_eq!(data.bag_frames().unwrap().indexed(), summary);
        assert_eq!(data.len(), frames.len());
        for (i, img) in frames.iter().enumerate() {
            assert_eq!(
                data.load(i).unwrap().image(),
                &Image::from_gray_owned(img.clone()),
                "frame {i}, summary {summary}"
            );
        }
    }
}

#[test]
fn an_unknown_compression_is_named_with_the_fix() {
    let file = TempFile::new("bz2.mcap");
    for summary in [true, false] {
        fs::write(
            &file.0,
            hand_written_bag("bz2", &[pattern(8, 6, 1)], summary),
        )
        .unwrap();
        match expect_bag_error(Dataset::open(&file.0)) {
            e @ BagError::Compression { .. } => {
                let text = e.to_string();
                assert!(
                    text.contains("'bz2'") && text.contains("zstd") && text.contains("lz4"),
                    "{text}"
                );
            }
            other => panic!("expected a compression error, got {other}"),
        }
    }
}

/// image_transport's `compressedDepth` payload: the 12-byte header (format, `A`, `B`) and a
/// 16-bit PNG of `values`.
fn compressed_depth(format: &str, (w, h): (u32, u32), values: Vec<u16>, a: f32, b: f32) -> Vec<u8> {
    let png = ImageBuffer::<Luma<u16>, _>::from_raw(w, h, values).unwrap();
    let mut bytes = Cursor::new(Vec::new());
    DynamicImage::ImageLuma16(png)
        .write_to(&mut bytes, ImageFormat::Png)
        .unwrap();
    let mut data = 0i32.to_le_bytes().to_vec();
    data.extend(a.to_le_bytes());
    data.extend(b.to_le_bytes());
    data.extend(bytes.into_inner());
    compressed_image_message(0, format, &data)
}

#[test]
fn compressed_depth_png_decodes_to_metres() {
    // 16UC1: millimetres as stored (scale 1000), 0 is no depth.
    let msg = compressed_depth(
        "16UC1; compressedDepth png",
        (3, 1),
        vec![1500, 0, 65535],
        0.0,
        0.0,
    );
    let d = messages::depth(&msg, true, 1000.0).unwrap();
    assert_eq!((d.at(0, 0), d.at(1, 0), d.at(2, 0)), (1.5, 0.0, 65.535));
    // 32FC1: quantised inverse depth q = A / z + B; z = 2 m and 0.5 m, q = 0 no depth.
    let (a, b) = (100.0f32, -10.0f32);
    let q = |z: f32| (a / z + b) as u16;
    let msg = compressed_depth(
        "32FC1; compressedDepth png",
        (3, 1),
        vec![q(2.0), q(0.5), 0],
        a,
        b,
    );
    let d = messages::depth(&msg, true, 1000.0).unwrap();
    assert_eq!((d.at(0, 0), d.at(1, 0), d.at(2, 0)), (2.0, 0.5, 0.0));
    // Not an intensity image; a payload without its header is a typed error.
    assert!(matches!(
        messages::intensity(&msg, true),
        Err(MessageError::Encoding { .. })
    ));
    let short = compressed_image_message(0, "16UC1; compressedDepth png", &[0; 5]);
    assert!(matches!(
        messages::depth(&short, true, 1000.0),
        Err(MessageError::CompressedDepth { .. })
    ));

    // In a bag: the png topic is the image, the compressedDepth topic the depth, paired.
    let grey = pattern(3, 1, 2);
    let mut png = Cursor::new(Vec::new());
    DynamicImage::ImageLuma8(grey.clone())
        .write_to(&mut png, ImageFormat::Png)
        .unwrap();
    let mut w = BagWriter::new(Cursor::new(Vec::new()), true).unwrap();
    let depth = compressed_depth(
        "16UC1; compressedDepth png",
        (3, 1),
        vec![1500, 0, 2000],
        0.0,
        0.0,
    );
    w.write(
        "/cam/depth/compressedDepth",
        messages::COMPRESSED_IMAGE,
        5,
        &depth,
    )
    .unwrap();
    w.write(
        "/cam/image/compressed",
        messages::COMPRESSED_IMAGE,
        5,
        &compressed_image_message(0, "png", &png.into_inner()),
    )
    .unwrap();
    let file = TempFile::new("depth.mcap");
    fs::write(&file.0, w.finish().unwrap().into_inner()).unwrap();
    let data = Dataset::open(&file.0).unwrap();
    assert_eq!(data.len(), 1);
    let frame = data.load(0).unwrap();
    assert_eq!(frame.image(), &Image::from_gray_owned(grey));
    let d = frame
        .depth()
        .expect("the compressedDepth topic is the depth");
    assert_eq!((d.at(0, 0), d.at(1, 0), d.at(2, 0)), (1.5, 0.0, 2.0));
}
