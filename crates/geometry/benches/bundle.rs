//! Criterion benchmark of [`bundle_adjust`]: a window of 10 keyframes moving forward through
//! 2000 points (about 15000 observations, 0.5 px noise), the 8 free keyframes perturbed by
//! 0.5 degree and 5 cm and the points by 10 cm; one full solve (all rounds) per iteration.

#[path = "../tests/common/window.rs"]
mod window;

use criterion::{criterion_group, criterion_main, BatchSize, Criterion};
use vofront_geometry::bundle::{bundle_adjust, BundleConfig};

fn bench_bundle(c: &mut Criterion) {
    let mut w = window::forward_window(11, 10, 2000, 0.5, 0.0);
    window::perturb(&mut w.problem, 12, 2, 0.5f64.to_radians(), 0.05, 0.1);
    let cfg = BundleConfig::default();
    let report = bundle_adjust(&mut w.problem.clone(), &cfg).expect("well-posed window");
    eprintln!(
        "{} observations: {} rounds, {} iterations, {} culled",
        w.problem.observations.len(),
        report.rounds,
        report.iterations,
        report.culled.len()
    );
    let mut group = c.benchmark_group("bundle");
    group.sample_size(20);
    group.bench_function("bundle_10kf_2000pts", |b| {
        b.iter_batched(
            || w.problem.clone(),
            |mut problem| bundle_adjust(&mut problem, &cfg).expect("well-posed window"),
            BatchSize::LargeInput,
        )
    });
    group.finish();
}

criterion_group!(benches, bench_bundle);
criterion_main!(benches);
