//! Writes a ROS 2 bag of a rendered TUM RGB-D folder (as written by `room_sequence`) for the
//! Python tests: each frame's grey image as a `mono8` Image, its depth as a `32FC1` Image (the
//! metres the folder's reader gives) and the rendering camera as `CameraInfo`.
//! `cargo run --release -p vofront-python --example bag_sequence -- FOLDER OUT.mcap`

use std::fs::File;
use std::io::BufWriter;

use vofront::dataset::bag::messages::{CAMERA_INFO, IMAGE};
use vofront::dataset::bag::write::{camera_message, image_message, BagWriter, ImageLayout};
use vofront::dataset::Dataset;
use vofront_fixtures::scene::default_camera;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let (Some(folder), Some(out)) = (args.get(1), args.get(2)) else {
        eprintln!("usage: bag_sequence FOLDER OUT.mcap");
        std::process::exit(2);
    };
    let dataset = Dataset::open(folder)?;
    let mut bag = BagWriter::new(BufWriter::new(File::create(out)?), true)?;
    for i in 0..dataset.len() {
        let frame = dataset.load(i)?;
        let ns = (frame.timestamp() * 1e9).round() as u64;
        let (width, height) = frame.image().size();
        let layout = |encoding, bpp| ImageLayout {
            width,
            height,
            encoding,
            big_endian: false,
            step: width * bpp,
        };
        let grey = frame.image().data();
        bag.write(
            "/camera/image",
            IMAGE,
            ns,
            &image_message(ns, layout("mono8", 1), grey),
        )?;
        if let Some(depth) = frame.depth() {
            let metres: Vec<u8> = depth.data().iter().flat_map(|v| v.to_le_bytes()).collect();
            let msg = image_message(ns, layout("32FC1", 4), &metres);
            bag.write("/camera/depth", IMAGE, ns, &msg)?;
        }
        let info = camera_message(ns, (width, height), &default_camera());
        bag.write("/camera/camera_info", CAMERA_INFO, ns, &info)?;
    }
    bag.finish()?;
    Ok(())
}
