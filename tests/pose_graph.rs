//! The g2o pose graph of `odometry --graph`: written as the run goes, parsed back, information
//! equal to the inverse covariance of g2o's error, and edge residuals against the ground
//! truth distributed as chi-square with 6 degrees of freedom.

use nalgebra::{Isometry3, Matrix6, Vector3, Vector6};
use vofront::dataset::Dataset;
use vofront::fixtures::scene::{default_camera, room_trajectory, Scene};
use vofront::fixtures::tum::write_tum_sequence;
use vofront::odometry::feature_rgbd::{FeatureRgbdConfig, FeatureRgbdTracker};
use vofront::odometry::graph::{g2o_error_vector, g2o_information, parse_g2o, G2oSink};
use vofront::odometry::run::{run_with, RunControl};

/// Frames of the rendered room sequence.
const FRAMES: usize = 60;

#[test]
fn information_is_the_inverse_covariance_of_the_g2o_error() {
    // A covariance of (rho, phi) with correlations; g2o's error is (rho, phi / 2).
    let a = Matrix6::from_fn(|r, c| {
        ((r * 7 + c * 3) % 5) as f64 * 0.1 + if r == c { 1.0 } else { 0.0 }
    });
    let cov = (a * a.transpose()) * 1e-4;
    let info = g2o_information(&cov).expect("invertible");
    let s = Matrix6::from_diagonal(&Vector6::new(1.0, 1.0, 1.0, 0.5, 0.5, 0.5));
    let product = info * (s * cov * s);
    assert!((product - Matrix6::identity()).norm() < 1e-8, "{product}");
    assert!(g2o_information(&Matrix6::zeros()).is_none());
    // The error vector is (t, q_xyz) with q_w >= 0: half the rotation vector at small angles.
    let phi = Vector3::new(0.01, -0.02, 0.005);
    let e = g2o_error_vector(&Isometry3::new(Vector3::new(0.1, 0.2, 0.3), phi));
    assert!((e.fixed_rows::<3>(0) - Vector3::new(0.1, 0.2, 0.3)).norm() < 1e-12);
    assert!((e.fixed_rows::<3>(3) - phi / 2.0).norm() < 1e-6);
    let flipped = Isometry3::new(Vector3::zeros(), Vector3::new(0.0, 0.0, 6.2));
    assert!(g2o_error_vector(&flipped)[5].abs() < 0.05);
}

#[test]
fn malformed_g2o_lines_are_typed_errors() {
    assert!(parse_g2o("VERTEX_SE3:QUAT 0 1 2 3\n").is_err());
    assert!(parse_g2o("VERTEX_SE3:QUAT 0 0 0 0 0 0 0 0\n").is_err());
    assert!(parse_g2o("EDGE_SE3:QUAT 0 1 0 0 0 0 0 0 1\n").is_err());
    let g = parse_g2o("# comment\nFIX 0\nVERTEX_SE3:QUAT 3 1 2 3 0 0 0 1\n").unwrap();
    assert_eq!(g.vertices.len(), 1);
    assert!((g.vertex(3).unwrap().translation.vector - Vector3::new(1.0, 2.0, 3.0)).norm() < 1e-12);
}

#[test]
fn room_sequence_graph_parses_back_with_calibrated_edges() {
    let dir = std::env::temp_dir().join(format!("vofront-graph-{}", std::process::id()));
    let camera = default_camera();
    let truth = room_trajectory(FRAMES);
    write_tum_sequence(&dir, &Scene::box_room(5), &camera, (640, 480), &truth).unwrap();
    let dataset = Dataset::open(&dir).unwrap();
    let mut tracker = FeatureRgbdTracker::new(camera, FeatureRgbdConfig::default()).unwrap();
    let mut bytes = Vec::new();
    let out = {
        let mut sink = G2oSink::new(&mut bytes);
        run_with(&dataset, &mut tracker, &RunControl::default(), &mut sink).unwrap()
    };
    let text = String::from_utf8(bytes).unwrap();
    let graph = parse_g2o(&text).unwrap();
    // One vertex per keyframe, at the tracked pose; consecutive keyframes joined.
    let keyframes: Vec<usize> = out
        .records
        .iter()
        .filter(|r| r.estimate.as_ref().is_ok_and(|e| e.quality.keyframe))
        .map(|r| r.index)
        .collect();
    let ids: Vec<usize> = graph.vertices.iter().map(|(id, _)| *id).collect();
    assert_eq!(ids, keyframes);
    assert!(
        graph.edges.len() + 1 >= keyframes.len() / 2,
        "{} edges",
        graph.edges.len()
    );
    for (id, pose) in &graph.vertices {
        let tracked = out.records[*id].estimate.as_ref().unwrap().pose_wc;
        assert!((pose.to_homogeneous() - tracked.to_homogeneous()).norm() < 1e-9);
    }
    let mut chi2 = Vec::new();
    for edge in &graph.edges {
        let position = ids.iter().position(|&k| k == edge.to).unwrap();
        assert!(
            position > 0 && ids[position - 1] == edge.from,
            "edge {edge:?}"
        );
        let (x_i, x_j) = (
            graph.vertex(edge.from).unwrap(),
            graph.vertex(edge.to).unwrap(),
        );
        assert!(
            edge.chi2(x_i, x_j) < 1e-12,
            "the measurement is the tracked relative pose"
        );
        assert!((edge.information - edge.information.transpose()).norm() < 1e-9);
        // The truth, with the first frame at the origin as in the tracked trajectory.
        let origin = truth[0].inverse();
        chi2.push(edge.chi2(&(origin * truth[edge.from]), &(origin * truth[edge.to])));
    }
    // Accepted band for the mean: [2, 18], a third to three times the 6 DoF. A calibrated
    // covariance gives 6 on average, but the 60 frames give only 4-5 keyframe edges (the mean
    // of 4 chi-square(6) values has a standard deviation of 1.7), and the PnP covariance
    // models the current frame's pixel noise only: the keyframe points' own noise (ORB
    // positions, pyramid levels with 1.2^l times the noise) is pooled into one residual scale.
    // Measured: 4 edges, mean 8.2 (11.8, 3.0, 6.5, 11.8).
    let mean = chi2.iter().sum::<f64>() / chi2.len() as f64;
    eprintln!("{} edges, mean chi2 {mean:.2}: {chi2:.2?}", chi2.len());
    assert!((2.0..=18.0).contains(&mean), "mean chi2 {mean}");

    // The command line writes the same graph, and the metrics CSV ends with verdict, reasons.
    let (g2o, csv) = (dir.join("out.g2o"), dir.join("frames.csv"));
    let status = std::process::Command::new(env!("CARGO_BIN_EXE_vofront"))
        .arg("odometry")
        .arg(&dir)
        .args(["--method", "feature-rgbd", "--json", "--out"])
        .arg(dir.join("traj.txt"))
        .arg("--metrics")
        .arg(&csv)
        .arg("--graph")
        .arg(&g2o)
        .output()
        .unwrap();
    assert!(status.status.success(), "{status:?}");
    assert_eq!(std::fs::read_to_string(&g2o).unwrap(), text);
    let mut reader = csv::Reader::from_path(&csv).unwrap();
    let header: Vec<String> = reader.headers().unwrap().iter().map(String::from).collect();
    assert_eq!(header, vofront::odometry::run::METRICS_COLUMNS);
    let rows: Vec<csv::StringRecord> = reader.records().map(|r| r.unwrap()).collect();
    assert_eq!(rows.len(), FRAMES);
    for (row, record) in rows.iter().zip(&out.records) {
        let e = record.estimate.as_ref().unwrap();
        assert_eq!(&row[2], e.status.as_str());
        let verdict = e
            .pose_quality
            .as_ref()
            .map_or(String::new(), |q| q.verdict.to_string());
        assert_eq!(&row[11], verdict);
    }
    std::fs::remove_dir_all(&dir).ok();
}
