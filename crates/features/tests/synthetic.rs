//! ORB and matching on synthetic images with a known warp `I2(H x) = I1(x)`.

use nalgebra::Matrix3;
use vofront_features::{match_descriptors, FeatureError, Features, MatchConfig, Orb, OrbConfig};
use vofront_fixtures::image2d::{
    apply_homography, similarity, textured_image, to_gray8, warped_textured_image,
};
use vofront_image::Image;

const W: u32 = 640;
const H: u32 = 480;

/// Reprojection tolerance for "agrees with the true warp", level-0 pixels.
const INLIER_PX: f32 = 3.0;
/// Keypoint repeatability floor: fraction of image-1 keypoints (whose warp lands inside
/// image 2) with an image-2 keypoint within `INLIER_PX`. FAST + Harris on a re-rendered
/// (not interpolated) image repeats about 75-85 % here; a broken pyramid mapping or
/// detector falls far below.
const REPEATABILITY_FLOOR: f64 = 0.6;
/// Fraction of ratio-test matches consistent with the warp within `INLIER_PX`. Steered BRIEF
/// on a rotated / scaled view matches mostly correctly; a wrong orientation or pattern rotation
/// drops this towards 0.
const MATCH_PRECISION_FLOOR: f64 = 0.8;
/// Minimum number of correct matches out of 1000 features on 640x480.
const CORRECT_MATCHES_FLOOR: usize = 250;

fn orb(n: usize) -> Orb {
    Orb::new(OrbConfig {
        n_features: n,
        ..OrbConfig::default()
    })
    .expect("default config is valid")
}

fn pair(h: &Matrix3<f64>, seed: u64) -> (Image<u8>, Image<u8>) {
    (
        to_gray8(&textured_image(W, H, seed)),
        to_gray8(&warped_textured_image(W, H, seed, h)),
    )
}

fn inside(x: f64, y: f64) -> bool {
    x >= 0.0 && y >= 0.0 && x < W as f64 && y < H as f64
}

/// Fraction of keypoints of `f1` that are found again in `f2` after the warp.
fn repeatability(f1: &Features, f2: &Features, h: &Matrix3<f64>) -> f64 {
    let (mut visible, mut repeated) = (0, 0);
    for i in 0..f1.len() {
        let Some((x, y)) = apply_homography(h, f1.xs()[i] as f64, f1.ys()[i] as f64) else {
            continue;
        };
        // Only points whose neighbourhood is inside image 2 can be detected there.
        if !(x > 25.0 && y > 25.0 && x < W as f64 - 25.0 && y < H as f64 - 25.0) {
            continue;
        }
        visible += 1;
        let near = (0..f2.len()).any(|j| {
            let (dx, dy) = (f2.xs()[j] as f64 - x, f2.ys()[j] as f64 - y);
            dx * dx + dy * dy <= (INLIER_PX * INLIER_PX) as f64
        });
        repeated += usize::from(near);
    }
    repeated as f64 / visible.max(1) as f64
}

/// (correct, total) ratio-test matches of `f1` to `f2` under the warp `h`.
fn correct_matches(f1: &Features, f2: &Features, h: &Matrix3<f64>) -> (usize, usize) {
    let matches = match_descriptors(f1.descriptors(), f2.descriptors(), &MatchConfig::default());
    let correct = matches
        .iter()
        .filter(|m| {
            let (q, t) = (m.query as usize, m.train as usize);
            apply_homography(h, f1.xs()[q] as f64, f1.ys()[q] as f64).is_some_and(|(x, y)| {
                let (dx, dy) = (f2.xs()[t] as f64 - x, f2.ys()[t] as f64 - y);
                inside(x, y) && dx * dx + dy * dy <= (INLIER_PX * INLIER_PX) as f64
            })
        })
        .count();
    (correct, matches.len())
}

fn check_warp(h: &Matrix3<f64>, seed: u64, what: &str) {
    let (i1, i2) = pair(h, seed);
    let orb = orb(1000);
    let f1 = orb.detect_and_describe(&i1).unwrap();
    let f2 = orb.detect_and_describe(&i2).unwrap();
    assert!(
        f1.len() >= 900 && f2.len() >= 900,
        "{what}: {} {}",
        f1.len(),
        f2.len()
    );
    let rep = repeatability(&f1, &f2, h);
    let (correct, total) = correct_matches(&f1, &f2, h);
    let precision = correct as f64 / total.max(1) as f64;
    eprintln!("{what}: repeatability {rep:.3}, matches {correct}/{total} correct");
    assert!(rep >= REPEATABILITY_FLOOR, "{what}: repeatability {rep}");
    assert!(
        precision >= MATCH_PRECISION_FLOOR,
        "{what}: precision {precision}"
    );
    assert!(
        correct >= CORRECT_MATCHES_FLOOR,
        "{what}: {correct} correct"
    );
}

#[test]
fn similarity_warp_is_matched_within_3px() {
    // 20 degrees, scale 1.15, shifted.
    let h = similarity(20f64.to_radians(), 1.15, 320.0, 240.0, 12.0, -7.0);
    check_warp(&h, 11, "similarity");
}

#[test]
fn homography_warp_is_matched_within_3px() {
    // A mild perspective: similarity followed by a projective row.
    let s = similarity(-10f64.to_radians(), 0.9, 320.0, 240.0, -5.0, 4.0);
    let p = Matrix3::new(1.0, 0.02, 0.0, -0.01, 1.0, 0.0, 2e-4, -1e-4, 1.0);
    check_warp(&(p * s), 5, "homography");
}

/// Orientation error tolerance in degrees after an in-plane rotation (intensity centroid of
/// a re-rendered patch; quantised keypoint positions move the disc by up to half a pixel).
const ANGLE_TOL_DEG: f32 = 4.0;
/// Median Hamming distance floor for a keypoint and its rotated self (out of 256 bits;
/// unrelated descriptors sit near 128).
const SELF_DISTANCE_CEIL: u32 = 35;

#[test]
fn orientation_follows_rotation_and_descriptor_stays_close() {
    for (deg, seed) in [(30.0f64, 3u64), (-75.0, 4), (160.0, 8)] {
        let h = similarity(deg.to_radians(), 1.0, 320.0, 240.0, 0.0, 0.0);
        let (i1, i2) = pair(&h, seed);
        let orb = orb(800);
        let f1 = orb.detect_and_describe(&i1).unwrap();
        let f2 = orb.detect_and_describe(&i2).unwrap();
        let (mut angle_err, mut dist) = (Vec::new(), Vec::new());
        for i in 0..f1.len() {
            let (x, y) = apply_homography(&h, f1.xs()[i] as f64, f1.ys()[i] as f64).unwrap();
            // The same keypoint in image 2: same level, within 1 level-0 pixel.
            let Some(j) = (0..f2.len()).find(|&j| {
                let (dx, dy) = (f2.xs()[j] as f64 - x, f2.ys()[j] as f64 - y);
                f2.levels()[j] == f1.levels()[i] && f1.levels()[i] == 0 && dx * dx + dy * dy <= 1.0
            }) else {
                continue;
            };
            let turn = (f2.angles()[j] - f1.angles()[i]).to_degrees();
            angle_err.push(((turn - deg as f32 + 540.0).rem_euclid(360.0) - 180.0).abs());
            dist.push(f1.descriptors()[i].hamming(&f2.descriptors()[j]));
        }
        assert!(
            angle_err.len() >= 50,
            "{deg}: only {} pairs",
            angle_err.len()
        );
        angle_err.sort_by(f32::total_cmp);
        dist.sort_unstable();
        let med_angle = angle_err[angle_err.len() / 2];
        let med_dist = dist[dist.len() / 2];
        eprintln!("rotation {deg}: {} pairs, median angle error {med_angle:.2} deg, median distance {med_dist}", dist.len());
        assert!(med_angle <= ANGLE_TOL_DEG, "{deg}: {med_angle}");
        assert!(med_dist <= SELF_DISTANCE_CEIL, "{deg}: {med_dist}");
    }
}

#[test]
fn keypoints_spread_over_the_image_and_respect_levels() {
    let img = to_gray8(&textured_image(W, H, 21));
    let f = orb(1000).detect_and_describe(&img).unwrap();
    assert!(f.len() >= 950 && f.len() <= 1000, "{}", f.len());
    // Every 4x4 block of the image receives features.
    let mut blocks = [0usize; 16];
    for i in 0..f.len() {
        let (bx, by) = (
            (f.xs()[i] / W as f32 * 4.0) as usize,
            (f.ys()[i] / H as f32 * 4.0) as usize,
        );
        blocks[by.min(3) * 4 + bx.min(3)] += 1;
    }
    assert!(blocks.iter().all(|&b| b >= 20), "{blocks:?}");
    for i in 0..f.len() {
        assert!((f.scales()[i] - 1.2f32.powi(f.levels()[i] as i32)).abs() < 1e-4);
        assert!(f.xs()[i] >= 18.0 && f.ys()[i] >= 18.0 && f.xs()[i] < W as f32 - 18.0);
        assert!(f.angles()[i].is_finite() && f.responses()[i].is_finite());
    }
    // Several levels are used, level 0 the most.
    let l0 = f.levels().iter().filter(|&&l| l == 0).count();
    assert!(f.levels().iter().any(|&l| l >= 4) && l0 > f.len() / 5);
}

#[test]
fn bad_input_gives_empty_results_or_typed_errors() {
    let orb = orb(500);
    for (w, h) in [(0, 0), (10, 10), (38, 300), (300, 38)] {
        let f = orb.detect_and_describe(&Image::filled(w, h, 0)).unwrap();
        assert!(f.is_empty(), "{w}x{h}");
    }
    let flat = Image::filled(200, 150, 90u8);
    assert!(orb.detect_and_describe(&flat).unwrap().is_empty());
    let textured = to_gray8(&textured_image(200, 150, 2));
    let none = Orb::new(OrbConfig {
        n_features: 0,
        ..OrbConfig::default()
    })
    .unwrap();
    assert!(none.detect_and_describe(&textured).unwrap().is_empty());
    for cfg in [
        OrbConfig {
            scale_levels: 0,
            ..OrbConfig::default()
        },
        OrbConfig {
            scale_factor: 1.0,
            ..OrbConfig::default()
        },
        OrbConfig {
            scale_factor: f32::NAN,
            ..OrbConfig::default()
        },
        OrbConfig {
            fast_threshold: 5,
            min_fast_threshold: 9,
            ..OrbConfig::default()
        },
        OrbConfig {
            patch_size: 15,
            ..OrbConfig::default()
        },
        OrbConfig {
            spread_candidates: 0.5,
            ..OrbConfig::default()
        },
    ] {
        assert!(matches!(Orb::new(cfg), Err(FeatureError::InvalidConfig(_))));
    }
    assert!(match_descriptors(&[], &[], &MatchConfig::default()).is_empty());
    assert!(Orb::new(OrbConfig::ranked()).is_ok());
}
