//! Writes a rendered EuRoC MAV sequence of the synthetic room (camera mounted on the body by a
//! non-identity `T_BS`) for the Python tests, with the camera ground truth beside it:
//! `cargo run --release -p vofront-python --example euroc_sequence -- DIR [FRAMES]` writes
//! `DIR/mav0/` and `DIR/camera_groundtruth.txt` (TUM lines, camera-to-world).

use std::io::Write;
use std::path::Path;

use vofront_fixtures::euroc::{
    mounted_camera_in_body, write_euroc_sequence, EUROC_FIRST_NS, EUROC_FRAME_NS,
};
use vofront_fixtures::scene::{default_camera, room_trajectory, Scene};
use vofront_fixtures::tum::tum_pose_line;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let Some(dir) = args.get(1) else {
        eprintln!("usage: euroc_sequence DIR [FRAMES]");
        std::process::exit(2);
    };
    let frames: usize = args.get(2).map_or(Ok(30), |s| s.parse())?;
    let dir = Path::new(dir);
    let poses = room_trajectory(frames);
    let t_bs = mounted_camera_in_body(std::f64::consts::FRAC_PI_2);
    write_euroc_sequence(
        dir,
        &Scene::box_room(1),
        &default_camera(),
        (640, 480),
        &poses,
        &t_bs,
    )?;
    let mut truth = std::fs::File::create(dir.join("camera_groundtruth.txt"))?;
    for (i, pose) in poses.iter().enumerate() {
        let ns = EUROC_FIRST_NS + i as u64 * EUROC_FRAME_NS;
        let stamp = format!("{}.{:09}", ns / 1_000_000_000, ns % 1_000_000_000);
        writeln!(truth, "{}", tum_pose_line(&stamp, pose))?;
    }
    Ok(())
}
