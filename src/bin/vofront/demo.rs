//! `vofront` without arguments: a synthetic scene pair with known motion, every estimator,
//! the errors against the truth, and the pictures in `vofront-out/`.

use std::path::Path;

use nalgebra::Isometry3;
use vofront::core::lie::{direction_angle_deg, rotation_angle_deg};
use vofront::dataset::Dataset;
use vofront::direct::{align_translation, TranslationConfig};
use vofront::fixtures::image2d::{textured_image, to_gray8, translation, warped_textured_image};
use vofront::fixtures::scene::{default_camera, pose_wc, room_trajectory, Scene};
use vofront::fixtures::tum::write_tum_sequence;
use vofront::odometry::registry::{Session, TrackerKind, TrackerOptions};

use vofront::two_view::Method;

use crate::odometry_cmd::{report, track};
use crate::two_view::{estimate, print_text, write_pictures, Inputs};

/// Where the demo writes its pictures.
const OUT_DIR: &str = "vofront-out";
/// Frames of the synthetic room sequence.
const SEQUENCE_FRAMES: usize = 60;

fn report_pose(name: &str, estimate: &Isometry3<f64>, truth: &Isometry3<f64>, metric: bool) {
    let rot = rotation_angle_deg(&estimate.rotation, &truth.rotation);
    let (t, tt) = (estimate.translation.vector, truth.translation.vector);
    if metric {
        outln!(
            "  {name:<11} rotation error {rot:.4} deg, translation error {:.2} mm",
            (t - tt).norm() * 1e3
        );
    } else {
        outln!(
            "  {name:<11} rotation error {rot:.4} deg, translation direction error {:.3} deg",
            direction_angle_deg(&t, &tt)
        );
    }
}

/// Runs the demo.
pub fn run() -> Result<(), String> {
    let room = Scene::box_room(1);
    let camera = default_camera();
    let t_w1 = pose_wc([0.0, 0.0, 0.0], 0.0, 0.0, 0.0);
    let t_w2 = pose_wc([0.15, -0.03, 0.06], -0.06, 0.02, 0.01);
    let truth = t_w2.inverse() * t_w1;
    let view1 = room.render(&camera, 640, 480, &t_w1);
    let view2 = room.render(&camera, 640, 480, &t_w2);
    let inputs = Inputs {
        img1: to_gray8(&view1.image),
        img2: to_gray8(&view2.image),
        depth1: Some(view1.depth),
        camera,
        method: Method::All,
        features: 2000,
        stereo: None,
    };
    outln!(
        "synthetic room, 640x480, camera moved {:.0} mm and turned {:.2} deg between the frames",
        truth.translation.vector.norm() * 1e3,
        truth.rotation.angle().to_degrees()
    );
    let outcome = estimate(&inputs);
    print_text(&outcome);

    outln!("errors against the true motion:");
    match &outcome.feature {
        Some(Ok(f)) => report_pose("feature", &f.estimate.pose, &truth, false),
        Some(Err(e)) => outln!("  feature     failed: {e}"),
        None => {}
    }
    match &outcome.se3 {
        Some(Ok((s, _))) => report_pose("direct SE3", &s.pose, &truth, true),
        Some(Err(e)) => outln!("  direct SE3  failed: {e}"),
        None => {}
    }
    let shift = (2.3, -1.7);
    let moved = warped_textured_image(640, 480, 7, &translation(shift.0, shift.1));
    let fit = align_translation(
        &to_gray8(&textured_image(640, 480, 7)).to_f32(),
        &to_gray8(&moved).to_f32(),
        &TranslationConfig::default(),
    )
    .map_err(|e| format!("direct 2D on the shifted texture: {e}"))?;
    outln!(
        "  direct 2D   shift ({:+.3}, {:+.3}) px for a true ({:+.3}, {:+.3}): error {:.4} px",
        fit.d.x,
        fit.d.y,
        shift.0,
        shift.1,
        ((fit.d.x - shift.0).powi(2) + (fit.d.y - shift.1).powi(2)).sqrt()
    );

    write_pictures(Path::new(OUT_DIR), &inputs, &outcome)?;
    outln!("pictures written to {OUT_DIR}/");
    if !outcome.any_estimate() {
        return Err("no estimator produced an estimate".into());
    }
    run_sequence(&room, camera)
}

/// Writes a rendered room sequence as a TUM RGB-D folder and tracks it with every method.
fn run_sequence(room: &Scene, camera: vofront::core::Camera) -> Result<(), String> {
    let dir = Path::new(OUT_DIR).join("room_sequence");
    write_tum_sequence(
        &dir,
        room,
        &camera,
        (640, 480),
        &room_trajectory(SEQUENCE_FRAMES),
    )
    .map_err(|e| format!("cannot write {}: {e}", dir.display()))?;
    let dataset = Dataset::open(&dir).map_err(|e| e.to_string())?;
    outln!(
        "\nsynthetic TUM sequence of {SEQUENCE_FRAMES} frames written to {}",
        dir.display()
    );
    // The rendered room is seen by one camera: the trackers of a stereo rig sit it out.
    for &kind in TrackerKind::ALL.iter().filter(|k| !k.needs_right()) {
        let name = kind.name();
        let session = Session::new(dataset.clone(), kind, Some((camera, "rendered")))
            .map_err(|e| e.to_string())?;
        let mut tracker = session
            .tracker(&TrackerOptions::default())
            .map_err(|e| e.to_string())?;
        let out = track(&session.dataset, tracker.as_mut(), None);
        let traj = Path::new(OUT_DIR).join(format!("{name}_trajectory.txt"));
        out.trajectory.write_tum(&traj).map_err(|e| e.to_string())?;
        out!("{name:<12} ");
        report(
            &session,
            &out,
            Some(&Path::new(OUT_DIR).join(format!("{name}_plot.png"))),
        )?;
    }
    Ok(())
}
