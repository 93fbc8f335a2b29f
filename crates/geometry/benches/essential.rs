//! Five-point solver alone, and the relative-pose pipeline (RANSAC + refinement) on 1000
//! correspondences with 50% outliers.
//!
//! Input: the CSV of `opencv_peer.py essential-synth --dump FILE` when `VOFRONT_ESSENTIAL_CSV`
//! names it, else the same recipe generated here (K = 520, 520, 320, 240; X uniform in
//! [-2, 2] x [-1.5, 1.5] x [2, 8]; R = Rodrigues(0.05, 0.1, 0.02); t = (0.3, 0.05, 0.1);
//! 0.5 px noise; 50% outliers uniform in the 640x480 image).

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use nalgebra::{Rotation3, Vector2, Vector3};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use vofront_geometry::camera::{Camera, Pinhole};
use vofront_geometry::essential::essential_5pt;
use vofront_geometry::relative_pose::{estimate_relative_pose, RelativePoseConfig};

use vofront_fixtures::noise::gauss;

fn synthetic(n: usize) -> (Vec<Vector2<f64>>, Vec<Vector2<f64>>) {
    let mut rng = StdRng::seed_from_u64(0);
    let r = Rotation3::new(Vector3::new(0.05, 0.1, 0.02));
    let t = Vector3::new(0.3, 0.05, 0.1);
    let project =
        |p: Vector3<f64>| Vector2::new(520.0 * p.x / p.z + 320.0, 520.0 * p.y / p.z + 240.0);
    let (mut x1, mut x2) = (Vec::with_capacity(n), Vec::with_capacity(n));
    for _ in 0..n {
        let p = Vector3::new(
            rng.random_range(-2.0..2.0),
            rng.random_range(-1.5..1.5),
            rng.random_range(2.0..8.0),
        );
        let a = project(p) + Vector2::new(gauss(&mut rng), gauss(&mut rng)) * 0.5;
        let mut b = project(r * p + t) + Vector2::new(gauss(&mut rng), gauss(&mut rng)) * 0.5;
        if rng.random_bool(0.5) {
            b = Vector2::new(rng.random_range(0.0..640.0), rng.random_range(0.0..480.0));
        }
        x1.push(a);
        x2.push(b);
    }
    (x1, x2)
}

fn load() -> (Vec<Vector2<f64>>, Vec<Vector2<f64>>) {
    let Ok(path) = std::env::var("VOFRONT_ESSENTIAL_CSV") else {
        return synthetic(1000);
    };
    let text = std::fs::read_to_string(&path).expect("VOFRONT_ESSENTIAL_CSV must be readable");
    let (mut x1, mut x2) = (Vec::new(), Vec::new());
    for line in text.lines().skip(1) {
        let v: Vec<f64> = line
            .split(',')
            .filter_map(|s| s.trim().parse().ok())
            .collect();
        if v.len() >= 4 {
            x1.push(Vector2::new(v[0], v[1]));
            x2.push(Vector2::new(v[2], v[3]));
        }
    }
    (x1, x2)
}

fn bench(c: &mut Criterion) {
    let cam = Camera::pinhole(Pinhole::new(520.0, 520.0, 320.0, 240.0).expect("valid intrinsics"));
    let (x1, x2) = load();

    // Five-point solver on five inlier-quality correspondences.
    let r = Rotation3::new(Vector3::new(0.05, 0.1, 0.02));
    let t = Vector3::new(0.3, 0.05, 0.1);
    let pts = [
        [0.3, 0.2, 3.0],
        [-1.5, 0.7, 4.0],
        [1.2, -1.0, 5.0],
        [0.2, 1.3, 2.5],
        [-0.8, -0.6, 6.0],
    ];
    let a: [Vector3<f64>; 5] = std::array::from_fn(|i| Vector3::from(pts[i]).normalize());
    let b: [Vector3<f64>; 5] = std::array::from_fn(|i| (r * Vector3::from(pts[i]) + t).normalize());
    let mut sols = Vec::with_capacity(10);
    c.bench_function("essential_5pt", |bench| {
        bench.iter(|| {
            essential_5pt(black_box(&a), black_box(&b), &mut sols);
            black_box(sols.len())
        })
    });

    let cfg = RelativePoseConfig::default();
    c.bench_function("relative_pose_1000_50pct_outliers", |bench| {
        bench.iter(|| {
            estimate_relative_pose(black_box(&x1), black_box(&x2), &cam, &cfg).expect("solvable")
        })
    });
    let no_refine = RelativePoseConfig {
        refine: false,
        ..cfg
    };
    c.bench_function("relative_pose_1000_50pct_outliers_no_refine", |bench| {
        bench.iter(|| {
            estimate_relative_pose(black_box(&x1), black_box(&x2), &cam, &no_refine)
                .expect("solvable")
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
