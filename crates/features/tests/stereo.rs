//! Stereo matching on rendered rectified pairs with exact depth: the street scene seen by a
//! left camera and by a right camera `b` metres to its right (same orientation and pinhole, so
//! the pair is rectified), where every left pixel's true disparity is `f b / Z`.

use nalgebra::{Isometry3, Translation3};
use vofront_features::{match_stereo, FeatureError, Features, Orb, OrbConfig, StereoConfig};
use vofront_fixtures::driving::DrivingSequence;
use vofront_fixtures::image2d::{brightness, to_gray8};
use vofront_image::Image;

/// KITTI's baseline, metres.
const BASELINE: f64 = 0.54;

struct Pair {
    left: Image<u8>,
    right: Image<u8>,
    depth: Image<f32>,
    fx: f64,
}

/// Frame `i` of a rendered drive as a rectified stereo pair; `right_gain` scales the right
/// image's brightness (cameras with different exposure).
fn stereo_pair(seed: u64, i: usize, right_gain: f32) -> Pair {
    let drive = DrivingSequence::new(seed, i + 1);
    let t_wl = drive.poses_wc[i];
    // The right camera's centre is `b` along the left camera's x axis.
    let t_wr: Isometry3<f64> = t_wl * Translation3::new(BASELINE, 0.0, 0.0);
    let (w, h) = drive.size;
    let left = drive.scene.render(&drive.camera, w, h, &t_wl);
    let right = drive.scene.render(&drive.camera, w, h, &t_wr);
    Pair {
        left: to_gray8(&left.image),
        right: to_gray8(&brightness(&right.image, right_gain, 4.0)),
        depth: left.depth,
        fx: drive.camera.pinhole.fx,
    }
}

fn orb(image: &Image<u8>) -> Features {
    Orb::new(OrbConfig::default())
        .and_then(|o| o.detect_and_describe(image))
        .expect("ORB on a valid image")
}

/// `|d - f b / Z|` of each match, `Z` the depth rendered at the left keypoint's pixel;
/// matches on a depth edge (the 3x3 neighbourhood spans more than 2% in depth) are left out.
fn disparity_errors<'a>(
    pair: &'a Pair,
    left: &'a Features,
) -> impl Fn(u32, f32) -> Option<f64> + 'a {
    move |i, d| {
        let (x, y) = (
            left.xs()[i as usize].round() as i64,
            left.ys()[i as usize].round() as i64,
        );
        let (w, h) = (pair.depth.width() as i64, pair.depth.height() as i64);
        let mut zs = Vec::new();
        for dy in -1..=1 {
            for dx in -1..=1 {
                let (u, v) = (x + dx, y + dy);
                if u >= 0 && v >= 0 && u < w && v < h {
                    zs.push(f64::from(pair.depth.at(u as usize, v as usize)));
                }
            }
        }
        let (lo, hi) = zs
            .iter()
            .fold((f64::INFINITY, 0.0f64), |(a, b), &z| (a.min(z), b.max(z)));
        (lo > 0.0 && hi < 1.02 * lo).then(|| {
            let z = zs[zs.len() / 2];
            (f64::from(d) - pair.fx * BASELINE / z).abs()
        })
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

#[test]
fn disparities_of_a_rendered_street_are_sub_pixel_accurate() {
    for (seed, frame, gain) in [(3, 0, 1.0), (5, 10, 1.3)] {
        let pair = stereo_pair(seed, frame, gain);
        let (left, right) = (orb(&pair.left), orb(&pair.right));
        let matches = match_stereo(
            &left,
            &right,
            &pair.left,
            &pair.right,
            &StereoConfig::default(),
        )
        .unwrap();
        assert!(
            matches.len() * 3 >= left.len(),
            "seed {seed}: {} matches of {} left features",
            matches.len(),
            left.len()
        );
        let error = disparity_errors(&pair, &left);
        let errors: Vec<f64> = matches
            .iter()
            .filter_map(|m| error(m.left, m.disparity))
            .collect();
        let wrong = errors.iter().filter(|&&e| e > 1.0).count();
        assert!(errors.len() > 100, "seed {seed}: {} scored", errors.len());
        assert!(
            wrong * 50 <= errors.len(),
            "seed {seed}: {wrong} of {} matches off by more than 1 px",
            errors.len()
        );
        let med = median(errors);
        assert!(med < 0.08, "seed {seed}: median disparity error {med} px");
        for m in &matches {
            assert!(m.disparity >= 0.5 && m.disparity <= 192.0);
            assert!((left.xs()[m.left as usize] - m.right_x - m.disparity).abs() < 1e-4);
            let z = m.depth(pair.fx * BASELINE);
            let sigma = m.depth_sigma(pair.fx * BASELINE, 0.5);
            assert!(z > 0.0 && sigma > 0.0 && sigma < z);
        }
        let mut rights: Vec<u32> = matches.iter().map(|m| m.right).collect();
        rights.sort_unstable();
        rights.dedup();
        assert_eq!(rights.len(), matches.len(), "a right feature used twice");
    }
}

#[test]
fn an_unrelated_right_image_gives_almost_no_matches() {
    let pair = stereo_pair(3, 0, 1.0);
    let other = stereo_pair(8, 25, 1.0);
    let (left, right) = (orb(&pair.left), orb(&other.right));
    let matches = match_stereo(
        &left,
        &right,
        &pair.left,
        &other.right,
        &StereoConfig::default(),
    )
    .unwrap();
    assert!(
        matches.len() * 20 < left.len(),
        "{} matches of {} features between unrelated images",
        matches.len(),
        left.len()
    );
}

#[test]
fn the_disparity_range_bounds_the_matches() {
    let pair = stereo_pair(3, 0, 1.0);
    let (left, right) = (orb(&pair.left), orb(&pair.right));
    let cfg = StereoConfig {
        max_disparity: 8.0,
        ..StereoConfig::default()
    };
    let matches = match_stereo(&left, &right, &pair.left, &pair.right, &cfg).unwrap();
    assert!(!matches.is_empty());
    let error = disparity_errors(&pair, &left);
    for m in &matches {
        assert!(m.disparity <= 8.0);
        if let Some(e) = error(m.left, m.disparity) {
            assert!(
                e < 1.0,
                "a point nearer than the range matched at {} px",
                m.disparity
            );
        }
    }
}

#[test]
fn bad_configurations_and_sizes_are_typed_errors() {
    let pair = stereo_pair(3, 0, 1.0);
    let f = orb(&pair.left);
    let bad = [
        StereoConfig {
            min_disparity: 0.0,
            ..StereoConfig::default()
        },
        StereoConfig {
            max_disparity: f32::NAN,
            ..StereoConfig::default()
        },
        StereoConfig {
            ratio: Some(1.5),
            ..StereoConfig::default()
        },
        StereoConfig {
            search_px: 40,
            ..StereoConfig::default()
        },
    ];
    for cfg in bad {
        assert!(matches!(
            match_stereo(&f, &f, &pair.left, &pair.right, &cfg),
            Err(FeatureError::InvalidConfig(_))
        ));
    }
    let small = Image::filled(10, 10, 0u8);
    assert!(matches!(
        match_stereo(&f, &f, &pair.left, &small, &StereoConfig::default()),
        Err(FeatureError::InvalidConfig(_))
    ));
}
