//! RANSAC that cannot settle on a wrong model: two-view and PnP estimates on the rendered
//! driving street (road plane, facades, distant structure with little parallax at the image
//! centre) agree with the truth, within the noise, for 100 different sampler seeds.

use nalgebra::{Isometry3, Point3, Vector2};
use vofront::fixtures::driving::DrivingSequence;
use vofront::geometry::pnp::{solve_pnp_ransac, PnpConfig};
use vofront::geometry::{estimate_relative_pose, RansacConfig, RelativePoseConfig};

/// Seeds every estimate is repeated with.
const SEEDS: u64 = 100;
/// Pixel noise (standard deviation of each coordinate) of the synthetic matches.
const NOISE_PX: f64 = 0.5;
/// Fraction of matches replaced by random pixel pairs.
const OUTLIERS: f64 = 0.3;

/// A small seeded generator (SplitMix64) for the synthetic noise.
struct Noise(u64);

impl Noise {
    /// Uniform in `[0, 1)`.
    fn uniform(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Standard normal (Box-Muller).
    fn gauss(&mut self) -> f64 {
        let u1 = self.uniform().max(1e-12);
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * self.uniform()).cos()
    }
}

/// World points with their pixels in the two frames, index-aligned.
type Matches = (Vec<Point3<f64>>, Vec<Vector2<f64>>, Vec<Vector2<f64>>);

/// Matches `i -> j` of the driving street: exact projections plus noise, a fraction replaced
/// by random pairs; returns the world points too (for PnP).
fn noisy_matches(seq: &DrivingSequence, i: usize, j: usize, n: usize) -> Matches {
    let mut rng = Noise(1000 + i as u64);
    let (w, h) = (f64::from(seq.size.0), f64::from(seq.size.1));
    let mut out = (Vec::new(), Vec::new(), Vec::new());
    for (p, u1, u2) in seq.correspondences(i, j, n, 7 + i as u64) {
        let mut jitter = |u: Vector2<f64>| u + Vector2::new(rng.gauss(), rng.gauss()) * NOISE_PX;
        let (a, b) = (jitter(u1), jitter(u2));
        let b = if rng.uniform() < OUTLIERS {
            Vector2::new(rng.uniform() * w, rng.uniform() * h)
        } else {
            b
        };
        out.0.push(p);
        out.1.push(a);
        out.2.push(b);
    }
    out
}

/// Angle between two unit directions, degrees.
fn angle_deg(a: &nalgebra::Vector3<f64>, b: &nalgebra::Vector3<f64>) -> f64 {
    a.normalize()
        .dot(&b.normalize())
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees()
}

#[test]
fn two_view_pose_on_the_street_does_not_depend_on_the_seed() {
    let seq = DrivingSequence::new(3, 70);
    // A straight stretch (forward motion, epipole at the image centre) and one in the turn.
    for (i, j) in [(2, 3), (30, 31)] {
        let truth = seq.relative(i, j);
        let (_, x1, x2) = noisy_matches(&seq, i, j, 600);
        let mut worst = (0.0f64, 0.0f64);
        for seed in 0..SEEDS {
            let cfg = RelativePoseConfig {
                ransac: RansacConfig {
                    seed,
                    ..RelativePoseConfig::default().ransac
                },
                ..RelativePoseConfig::default()
            };
            let rel = estimate_relative_pose(&x1, &x2, &seq.camera, &cfg).expect("a pose");
            let rot = rel.rotation().angle_to(&truth.rotation).to_degrees();
            let dir = angle_deg(&rel.translation(), &truth.translation.vector);
            worst = (worst.0.max(rot), worst.1.max(dir));
        }
        // At 0.5 px noise on ~400 inliers and a 1 m baseline the rotation is good to about
        // 0.2 degrees and the direction to a few degrees; a wrong model is tens of degrees off.
        assert!(
            worst.0 < 0.3 && worst.1 < 4.0,
            "frames {i}->{j}: worst rotation {:.3} deg, direction {:.2} deg",
            worst.0,
            worst.1
        );
    }
}

#[test]
fn pnp_pose_on_the_street_does_not_depend_on_the_seed() {
    let seq = DrivingSequence::new(4, 40);
    let (i, j) = (10, 11);
    let truth: Isometry3<f64> = seq.poses_wc[j].inverse();
    let (world, _, px) = noisy_matches(&seq, i, j, 400);
    let mut worst = (0.0f64, 0.0f64);
    for seed in 0..SEEDS {
        let cfg = PnpConfig {
            ransac: RansacConfig {
                seed,
                ..PnpConfig::default().ransac
            },
            ..PnpConfig::default()
        };
        let fit = solve_pnp_ransac(&world, &px, &seq.camera, None, &cfg).expect("a pose");
        let rot = fit.pose.rotation.angle_to(&truth.rotation).to_degrees();
        let pos =
            (fit.pose.inverse().translation.vector - seq.poses_wc[j].translation.vector).norm();
        worst = (worst.0.max(rot), worst.1.max(pos));
    }
    assert!(
        worst.0 < 0.1 && worst.1 < 0.1,
        "worst rotation {:.3} deg, position {:.3} m",
        worst.0,
        worst.1
    );
}

/// The real pair of issue 13: KITTI 06 frames 0 -> 1 (the car drives straight ahead), 1500
/// ORB features, ratio 0.8. Seed 0 used to lock onto a sideways model with fewer inliers.
/// Seeds 0 and 7 did again with a per-cell floor of 96 px: a sideways motion turned by 7
/// degrees has its epipolar lines along the image rows, so it holds every match that moves
/// less than a pixel vertically (distant points, points near the horizon row), 425 of 506, and
/// the local optimisation skipped the hypotheses of the true motion (460 inliers) because 90%
/// of their inliers were the sideways model's (`RansacConfig::lo_skip_shared`, since turned
/// off). Four feature sets, 20 seeds each, with the two-view estimator's own RANSAC settings.
#[test]
fn two_view_pose_on_real_forward_driving_does_not_depend_on_the_seed() {
    use vofront::features::{Orb, OrbConfig};
    use vofront::geometry::{Camera, Pinhole};
    let dir =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/kitti_06/image_0");
    if !dir.exists() {
        eprintln!("skipped: {} not found", dir.display());
        return;
    }
    let camera =
        Camera::pinhole(Pinhole::new(707.0912, 707.0912, 601.8873, 183.1104).expect("intrinsics"));
    let images = ["000000.png", "000001.png"]
        .map(|name| vofront::input::load_gray(&dir.join(name)).expect("image"));
    for cell_floor in [0, 64, 96, 128] {
        let orb = Orb::new(OrbConfig {
            n_features: 1500,
            cell_floor,
            ..OrbConfig::default()
        })
        .expect("orb");
        let [a, b] = images
            .each_ref()
            .map(|image| orb.detect_and_describe(image).expect("features"));
        forward_for_every_seed(&a, &b, &camera, cell_floor);
    }
}

/// Asserts that the two-view pose of the matches of `a` to `b` is a forward motion for seeds
/// 0-19.
fn forward_for_every_seed(
    a: &vofront::features::Features,
    b: &vofront::features::Features,
    camera: &vofront::geometry::Camera,
    cell_floor: usize,
) {
    use vofront::features::{match_descriptors, MatchConfig};
    let matching = MatchConfig {
        ratio: Some(0.8),
        ..MatchConfig::default()
    };
    let matches = match_descriptors(a.descriptors(), b.descriptors(), &matching);
    let pixel = |f: &vofront::features::Features, i: u32| {
        Vector2::new(f64::from(f.xs()[i as usize]), f64::from(f.ys()[i as usize]))
    };
    let x1: Vec<_> = matches.iter().map(|m| pixel(a, m.query)).collect();
    let x2: Vec<_> = matches.iter().map(|m| pixel(b, m.train)).collect();
    for seed in 0..20 {
        let cfg = RelativePoseConfig {
            ransac: RansacConfig {
                seed,
                ..RelativePoseConfig::default().ransac
            },
            ..RelativePoseConfig::default()
        };
        let rel = estimate_relative_pose(&x1, &x2, camera, &cfg).expect("a pose");
        // Forward motion: x2 = R x1 + t with the camera moving along +Z gives t ~ (0, 0, -1).
        assert!(
            rel.translation().z < -0.99 && rel.rotation().angle().to_degrees() < 0.5,
            "cell floor {cell_floor}, seed {seed}: t = {:?}, {} inliers",
            rel.translation(),
            rel.inlier_count()
        );
    }
}
