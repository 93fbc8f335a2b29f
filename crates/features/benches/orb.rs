//! Criterion benchmarks: ORB detect+describe on 640x480 (1000 and 2000 features, one rayon
//! thread and the default pool) and kNN-2 matching of 2000 x 2000 descriptors.
//!
//! Uses the synthetic textured image, plus `../shared/data/tum_fr1_xyz_pairs/case_1/img_prev.png`
//! (relative to the workspace root) when that file exists.

use std::path::PathBuf;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use vofront_features::{knn2, Orb, OrbConfig};
use vofront_fixtures::image2d::{textured_image, to_gray8};
use vofront_image::Image;

/// Bench images: the synthetic one, and the TUM frame when present.
fn images() -> Vec<(&'static str, Image<u8>)> {
    let mut out = vec![("synthetic", to_gray8(&textured_image(640, 480, 1)))];
    let tum = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/data/tum_fr1_xyz_pairs/case_1/img_prev.png");
    match image::open(&tum) {
        Ok(img) => out.push(("tum_fr1", Image::from_gray_owned(img.to_luma8()))),
        Err(_) => eprintln!("skipping the TUM image: {} not readable", tum.display()),
    }
    out
}

fn detect_describe(c: &mut Criterion) {
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("a one-thread pool");
    let mut group = c.benchmark_group("orb_640x480");
    for (name, img) in images() {
        for n in [1000usize, 2000] {
            let orb = Orb::new(OrbConfig {
                n_features: n,
                ..OrbConfig::default()
            })
            .expect("valid config");
            group.bench_with_input(
                BenchmarkId::new(format!("{name}_1thread"), n),
                &n,
                |b, _| b.iter(|| one.install(|| orb.detect_and_describe(&img))),
            );
            group.bench_with_input(
                BenchmarkId::new(format!("{name}_default"), n),
                &n,
                |b, _| b.iter(|| orb.detect_and_describe(&img)),
            );
        }
    }
    group.finish();
}

fn matching(c: &mut Criterion) {
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("a one-thread pool");
    let orb = Orb::new(OrbConfig::default()).expect("valid config");
    let f1 = orb
        .detect_and_describe(&to_gray8(&textured_image(640, 480, 1)))
        .expect("features");
    let f2 = orb
        .detect_and_describe(&to_gray8(&textured_image(640, 480, 2)))
        .expect("features");
    let mut group = c.benchmark_group("knn2_2000x2000");
    group.bench_function("1thread", |b| {
        b.iter(|| one.install(|| knn2(f1.descriptors(), f2.descriptors())))
    });
    group.bench_function("default", |b| {
        b.iter(|| knn2(f1.descriptors(), f2.descriptors()))
    });
    group.finish();
}

criterion_group!(benches, detect_describe, matching);
criterion_main!(benches);
