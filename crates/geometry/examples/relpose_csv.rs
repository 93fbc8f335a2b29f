//! Runs [`estimate_relative_pose`] on correspondences from a CSV file and prints the result
//! as JSON (rotation matrix, unit translation, inliers, median time over repetitions).
//!
//! `cargo run --release -p vofront-geometry --example relpose_csv -- FILE.csv
//!  [--K fx,fy,cx,cy] [--dist k1,k2,p1,p2,k3] [--threshold px] [--reps N]`
//!
//! The CSV has a header line and rows `x1,y1,x2,y2[,...]` of pixel coordinates.

use std::time::Instant;

use nalgebra::Vector2;
use vofront_geometry::camera::{Camera, Distortion, Pinhole};
use vofront_geometry::relative_pose::{estimate_relative_pose, RelativePoseConfig};

fn parse_list(s: &str) -> Vec<f64> {
    s.split(',').filter_map(|v| v.trim().parse().ok()).collect()
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let path = args
        .first()
        .ok_or("usage: relpose_csv FILE.csv [--K ..] [--dist ..]")?;
    let mut k = vec![520.0, 520.0, 320.0, 240.0];
    let mut dist = vec![0.0; 5];
    let mut cfg = RelativePoseConfig::default();
    let mut reps = 1;
    let mut it = args.iter().skip(1);
    while let Some(flag) = it.next() {
        let value = it.next().ok_or("missing flag value")?;
        match flag.as_str() {
            "--K" => k = parse_list(value),
            "--dist" => dist = parse_list(value),
            "--threshold" => cfg.ransac.threshold = value.parse()?,
            "--reps" => reps = value.parse()?,
            "--min-parallax" => cfg.min_parallax_deg = value.parse()?,
            "--homography-ratio" => cfg.homography_ratio = value.parse()?,
            "--no-refine" => cfg.refine = value != "1",
            other => return Err(format!("unknown flag {other}").into()),
        }
    }
    if k.len() != 4 || dist.len() != 5 {
        return Err("--K needs 4 values and --dist 5".into());
    }
    let camera = Camera::new(
        Pinhole::new(k[0], k[1], k[2], k[3])?,
        Distortion::from_array([dist[0], dist[1], dist[2], dist[3], dist[4]]),
    );
    let text = std::fs::read_to_string(path)?;
    let (mut x1, mut x2) = (Vec::new(), Vec::new());
    for line in text.lines().skip(1) {
        let v = parse_list(line);
        if v.len() >= 4 {
            x1.push(Vector2::new(v[0], v[1]));
            x2.push(Vector2::new(v[2], v[3]));
        }
    }
    let mut times = Vec::with_capacity(reps);
    let mut result = None;
    for _ in 0..reps.max(1) {
        let start = Instant::now();
        result = Some(estimate_relative_pose(&x1, &x2, &camera, &cfg));
        times.push(start.elapsed().as_secs_f64() * 1e3);
    }
    times.sort_by(f64::total_cmp);
    let rel = result.expect("at least one repetition")?;
    let alt = rel
        .alternative
        .map_or(("null".to_string(), "null".to_string()), |a| {
            let m = a.rotation.to_rotation_matrix().into_inner();
            let t = a.translation.vector;
            (
                format!(
                    "[[{}, {}, {}], [{}, {}, {}], [{}, {}, {}]]",
                    m[(0, 0)],
                    m[(0, 1)],
                    m[(0, 2)],
                    m[(1, 0)],
                    m[(1, 1)],
                    m[(1, 2)],
                    m[(2, 0)],
                    m[(2, 1)],
                    m[(2, 2)]
                ),
                format!("[{}, {}, {}]", t.x, t.y, t.z),
            )
        });
    let r = rel.rotation().to_rotation_matrix();
    let m = r.matrix();
    println!(
        "{{\"R\": [[{}, {}, {}], [{}, {}, {}], [{}, {}, {}]], \"t\": [{}, {}, {}], \"model\": \"{:?}\", \
         \"inliers\": {}, \"triangulated\": {}, \"parallax_deg\": {:.3}, \"low_parallax\": {}, \
         \"homography_ratio\": {:.3}, \"iterations\": [{}, {}], \"ms\": {:.3}, \"n\": {}, \
         \"ambiguous\": {}, \"alt_R\": {}, \"alt_t\": {}}}",
        m[(0, 0)], m[(0, 1)], m[(0, 2)], m[(1, 0)], m[(1, 1)], m[(1, 2)], m[(2, 0)], m[(2, 1)], m[(2, 2)],
        rel.translation().x, rel.translation().y, rel.translation().z, rel.model, rel.inlier_count(),
        rel.triangulated(), rel.parallax_deg, rel.low_parallax, rel.homography_score_ratio,
        rel.iterations.essential, rel.iterations.homography, times[times.len() / 2], x1.len(), rel.ambiguous,
        alt.0, alt.1
    );
    Ok(())
}
