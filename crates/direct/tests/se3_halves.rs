//! [`Se3Reference::halves_disagreement`]: two halves of an alignment's pixels (the colours of
//! a checkerboard of [`HALF_CELL_PX`]-pixel cells) agree on the motion of a static scene, and
//! disagree by far more than their sigmas when the pixels of one half see panels that move
//! with the camera (a second motion, as of a vehicle driving beside it).

use nalgebra::Isometry3;
use vofront_direct::{RgbdFrame, Se3Config, Se3Reference, HALF_CELL_PX};
use vofront_fixtures::scene::{
    default_camera, panels_moving_with_camera, pose_wc, rescaled_camera, Scene,
};

const W: u32 = 320;
const H: u32 = 240;

/// The halves' disagreement, in combined sigmas, for the camera moving from `t_w1` to `t_w2`
/// through the box room, with or without panels moving with it in the even cells.
fn disagreement(panels: bool) -> f64 {
    let camera = rescaled_camera(&default_camera(), 0.5);
    let scene = |t_wc: &Isometry3<f64>| {
        let mut scene = Scene::box_room(5);
        if panels {
            let cell = f64::from(HALF_CELL_PX);
            let moving = panels_moving_with_camera(&camera, (W, H), t_wc, cell, 1.0, 100);
            scene.quads.extend(moving);
        }
        scene
    };
    let t_w1 = pose_wc([0.0, 0.0, 0.0], 0.0, 0.0, 0.0);
    let t_w2 = pose_wc([0.03, -0.01, 0.08], 0.01, -0.005, 0.0);
    let first = scene(&t_w1).render(&camera, W, H, &t_w1);
    let second = scene(&t_w2).render(&camera, W, H, &t_w2);
    let cfg = Se3Config::default();
    let frame = RgbdFrame::new(first.image, first.depth, &camera).expect("frame");
    let reference = Se3Reference::new(&frame, &cfg).expect("reference");
    let fit = reference
        .align(&second.image, &Isometry3::identity(), &cfg)
        .expect("alignment");
    reference
        .halves_disagreement(&second.image, &fit.pose, &cfg)
        .expect("both halves align")
}

#[test]
fn halves_agree_on_a_static_scene_and_part_when_one_sees_a_second_motion() {
    let still = disagreement(false);
    let moving = disagreement(true);
    println!("halves apart: static {still:.2}, panels {moving:.2} combined sigmas");
    assert!(still < 6.0, "static room: {still:.2} sigmas");
    assert!(
        moving > 20.0,
        "panels moving with the camera: {moving:.2} sigmas"
    );
}
