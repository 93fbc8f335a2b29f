//! The `vofront` command line. With no arguments it renders a synthetic scene pair with known
//! motion into `vofront-out/` and prints that motion.
use std::process::ExitCode;

use vofront::fixtures::image2d::to_gray8;
use vofront::fixtures::scene::{default_camera, room_trajectory, Scene};
use vofront::geometry::lie::se3_log;

fn main() -> ExitCode {
    let out = std::path::Path::new("vofront-out");
    let poses = room_trajectory(31);
    let (t_w1, t_w2) = (poses[0], poses[30]);
    let room = Scene::box_room(1);
    let camera = default_camera();
    if let Err(e) = std::fs::create_dir_all(out) {
        eprintln!("vofront: cannot create {}: {e}", out.display());
        return ExitCode::FAILURE;
    }
    for (name, pose) in [("frame1.png", t_w1), ("frame2.png", t_w2)] {
        let view = room.render(&camera, 640, 480, &pose);
        if let Err(e) = to_gray8(&view.image).save(out.join(name)) {
            eprintln!("vofront: cannot write {}: {e}", out.join(name).display());
            return ExitCode::FAILURE;
        }
    }
    let xi = se3_log(&(t_w2.inverse() * t_w1));
    println!(
        "synthetic pair written to {}/frame1.png, frame2.png",
        out.display()
    );
    println!("true motion T_21 as (rho, phi): {:.4}", xi.transpose());
    ExitCode::SUCCESS
}
