//! Writes a rendered TUM RGB-D sequence of the synthetic room (exact ground truth) for the
//! Python tests: `cargo run --release -p vofront-python --example room_sequence -- DIR [FRAMES]`.

use std::path::Path;

use vofront_fixtures::scene::{default_camera, room_trajectory, Scene};
use vofront_fixtures::tum::write_tum_sequence;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let Some(dir) = args.get(1) else {
        eprintln!("usage: room_sequence DIR [FRAMES]");
        std::process::exit(2);
    };
    let frames: usize = args.get(2).map_or(Ok(20), |s| s.parse())?;
    let poses = room_trajectory(frames);
    write_tum_sequence(
        Path::new(dir),
        &Scene::box_room(1),
        &default_camera(),
        (640, 480),
        &poses,
    )?;
    Ok(())
}
