//! The result types serialise as the records they are: `serde_json::to_value` of a
//! [`RelativePose`] holds every field under its Rust name with the struct's own values, the pose
//! in nalgebra's layout, and the quality record the `vofront` JSON prints.

use nalgebra::{Isometry3, Point3, Vector2, Vector3};
use serde_json::{json, Value};
use vofront_geometry::relative_pose::{estimate_relative_pose, RelativePose, RelativePoseConfig};
use vofront_geometry::{Camera, Pinhole};

/// A pose from 120 correspondences of a general scene, every sixth replaced by a gross outlier,
/// so that `inliers` holds both values and `points` both `Some` and `None`.
fn estimate() -> RelativePose {
    let cam = Camera::pinhole(Pinhole::new(520.0, 520.0, 320.0, 240.0).unwrap());
    let t21 = Isometry3::new(Vector3::new(0.3, 0.05, 0.1), Vector3::new(0.05, 0.1, 0.02));
    let (mut x1, mut x2) = (Vec::new(), Vec::new());
    for i in 0..120 {
        let f = i as f64;
        let p = Point3::new(
            (f * 0.37).sin() * 2.0,
            (f * 0.73).cos() * 1.5,
            2.0 + (f * 0.51).sin().abs() * 6.0,
        );
        x1.push(cam.project(&p.coords).unwrap());
        x2.push(if i % 6 == 0 {
            Vector2::new(
                320.0 + 250.0 * (f * 1.3).sin(),
                240.0 + 200.0 * (f * 0.7).cos(),
            )
        } else {
            cam.project(&(t21 * p).coords).unwrap()
        });
    }
    estimate_relative_pose(&x1, &x2, &cam, &RelativePoseConfig::default()).unwrap()
}

/// `Isometry3` as nalgebra writes it: the unit quaternion `[i, j, k, w]` and the translation.
fn isometry_json(pose: &Isometry3<f64>) -> Value {
    let (q, t) = (pose.rotation.quaternion(), pose.translation.vector);
    json!({"rotation": [q.i, q.j, q.k, q.w], "translation": [t.x, t.y, t.z]})
}

#[test]
fn relative_pose_serialises_every_field_with_its_value() {
    let rel = estimate();
    assert!(rel.inliers.contains(&false) && rel.inliers.contains(&true));
    let v = serde_json::to_value(&rel).unwrap();

    let mut keys: Vec<&str> = v.as_object().unwrap().keys().map(|k| k.as_str()).collect();
    keys.sort_unstable();
    assert_eq!(
        keys,
        [
            "alternative",
            "ambiguous",
            "homography_score_ratio",
            "inliers",
            "iterations",
            "low_parallax",
            "model",
            "parallax_deg",
            "points",
            "pose",
            "pure_rotation",
            "quality",
        ]
    );
    assert_eq!(v["pose"], isometry_json(&rel.pose));
    assert_eq!(v["model"], "essential");
    assert_eq!(v["inliers"], json!(rel.inliers));
    let points: Vec<Value> = rel
        .points
        .iter()
        .map(|p| p.map_or(Value::Null, |p| json!([p.x, p.y, p.z])))
        .collect();
    assert_eq!(v["points"], Value::Array(points));
    assert_eq!(v["parallax_deg"], json!(rel.parallax_deg));
    assert_eq!(v["low_parallax"], json!(rel.low_parallax));
    assert_eq!(v["pure_rotation"], json!(rel.pure_rotation));
    assert_eq!(v["ambiguous"], json!(rel.ambiguous));
    assert_eq!(
        v["alternative"],
        rel.alternative.as_ref().map_or(Value::Null, isometry_json)
    );
    assert_eq!(
        v["homography_score_ratio"],
        json!(rel.homography_score_ratio)
    );
    assert_eq!(
        v["iterations"],
        json!({"essential": rel.iterations.essential, "homography": rel.iterations.homography})
    );

    // The quality record, flattened as the CLI prints it: verdict and reasons as snake_case
    // names, the support counts at the top level of the object.
    let q = &v["quality"];
    assert_eq!(*q, serde_json::to_value(&rel.quality).unwrap());
    assert_eq!(q["verdict"], rel.quality.verdict.to_string());
    assert_eq!(q["verdict"], "ok");
    let reasons: Vec<&str> = rel.quality.reasons.iter().map(|r| r.name()).collect();
    assert_eq!(q["reasons"], json!(reasons));
    assert_eq!(q["inliers"], json!(rel.inlier_count()));
    assert_eq!(q["candidates"], json!(rel.inliers.len()));
    assert_eq!(q["sigma"], json!(rel.quality.sigma));
}
