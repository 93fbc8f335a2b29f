//! PnP RANSAC with refinement on 250 correspondences (0.7 px noise, 10% outliers, the size
//! and mix of a tracked KITTI frame), without a prior and with the tracker's two priors: the
//! motion model's prediction (a few centimetres and tenths of a degree off) and the pose
//! found by the first matching pass (near exact).
//!
//! Scene: K = 718, 718, 607, 185 (1241x376); points uniform in [-8, 8] x [-2, 2] x [4, 40] m.

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use nalgebra::{Isometry3, Point3, Vector2, Vector3};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use vofront_fixtures::noise::gauss;
use vofront_geometry::camera::{Camera, Pinhole};
use vofront_geometry::pnp::{solve_pnp_ransac, PnpConfig};

/// The true `T_cw`, the world points and their pixels.
fn scene(camera: &Camera) -> (Isometry3<f64>, Vec<Point3<f64>>, Vec<Vector2<f64>>) {
    let mut rng = StdRng::seed_from_u64(0);
    let t_cw = Isometry3::new(
        Vector3::new(0.1, -0.05, -1.2),
        Vector3::new(0.01, 0.04, 0.0),
    );
    let (mut world, mut pixels) = (Vec::new(), Vec::new());
    while world.len() < 250 {
        let p = Point3::new(
            rng.random_range(-8.0..8.0),
            rng.random_range(-2.0..2.0),
            rng.random_range(4.0..40.0),
        );
        let Some(u) = camera.project(&(t_cw * p).coords) else {
            continue;
        };
        if !(0.0..1241.0).contains(&u.x) || !(0.0..376.0).contains(&u.y) {
            continue;
        }
        let u = if rng.random_bool(0.1) {
            Vector2::new(rng.random_range(0.0..1241.0), rng.random_range(0.0..376.0))
        } else {
            u + Vector2::new(gauss(&mut rng), gauss(&mut rng)) * 0.7
        };
        world.push(p);
        pixels.push(u);
    }
    (t_cw, world, pixels)
}

fn bench(c: &mut Criterion) {
    let camera = Camera::pinhole(Pinhole::new(718.0, 718.0, 607.0, 185.0).unwrap());
    let (t_cw, world, pixels) = scene(&camera);
    let cfg = PnpConfig::default();
    let predicted = Isometry3::new(
        Vector3::new(0.03, -0.02, 0.05),
        Vector3::new(0.002, -0.003, 0.001),
    ) * t_cw;
    let located = solve_pnp_ransac(&world, &pixels, &camera, None, &cfg)
        .expect("a pose")
        .pose;
    let mut group = c.benchmark_group("pnp_250");
    for (name, prior) in [
        ("no_prior", None),
        ("predicted_prior", Some(predicted)),
        ("located_prior", Some(located)),
    ] {
        group.bench_function(name, |b| {
            b.iter(|| {
                solve_pnp_ransac(black_box(&world), &pixels, &camera, prior, &cfg).expect("a pose")
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
