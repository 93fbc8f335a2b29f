//! Trajectory evaluation against the `evo` package, Umeyama recovery, and the plot writer.

use std::path::Path;

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use proptest::prelude::*;
use vofront::eval::plot::{render_plot, write_plot, ERROR_COLOUR, EST_COLOUR, GT_COLOUR};
use vofront::eval::{ate, rpe, umeyama, Alignment, EvalConfig, EvalError, Stats};
use vofront::fixtures::scene::room_trajectory;
use vofront::trajectory::Trajectory;

/// Agreement required with evo's printed statistics (the task's acceptance bound).
const EVO_TOLERANCE: f64 = 1e-6;
/// Umeyama on exact correspondences is closed-form: only rounding remains.
const EXACT_TOLERANCE: f64 = 1e-9;

/// evo's statistics `[rmse, mean, median, std, min, max, sse]` and count.
struct EvoStats([f64; 7], usize);

// Known values from evo v1.38.1 (the `evo` package in /root/.cache/vofront-peers), on
// tests/data/evo_gt.txt and tests/data/evo_est.txt (written by tests/data/make_evo_pair.py),
// read from `stats.json` of `--save_results`:
//   evo_ape tum evo_gt.txt evo_est.txt [--align [--correct_scale]] --no_warnings
//   evo_rpe tum evo_gt.txt evo_est.txt --delta 1 --delta_unit f
//           --pose_relation {trans_part, angle_deg} [--align --correct_scale] --no_warnings
// evo associated 100 of the 103 estimated poses (three stamps are 20 ms off).
const APE_NONE: EvoStats = EvoStats(
    [
        2.4170259051732534,
        2.4162846945004848,
        2.3998056735512066,
        0.059854000712444184,
        2.3412828046692837,
        2.5596937562507764,
        584.2014226278585,
    ],
    100,
);
const APE_SE3: EvoStats = EvoStats(
    [
        0.0643461137013656,
        0.06037422913518028,
        0.05718914605159583,
        0.022257016978962367,
        0.023878411473108475,
        0.12826305223534532,
        0.4140422348469069,
    ],
    100,
);
const APE_SIM3: EvoStats = EvoStats(
    [
        0.012286853033885627,
        0.011891923435773659,
        0.01248202370471337,
        0.003090131789099242,
        0.0008465519676899602,
        0.017557316171792778,
        0.015096675747630448,
    ],
    100,
);
const RPE_TRANS: EvoStats = EvoStats(
    [
        0.013566660784055109,
        0.013021241035735542,
        0.013397749226226541,
        0.003808092267644727,
        0.003291226967751007,
        0.02531427726193943,
        0.018221374198132256,
    ],
    99,
);
const RPE_ANGLE_DEG: EvoStats = EvoStats(
    [
        0.8214581792629835,
        0.7845403574026542,
        0.8258440162450527,
        0.243495313886267,
        0.2605301039788813,
        1.1307554473823933,
        66.80456048752754,
    ],
    99,
);
const RPE_TRANS_SIM3: EvoStats = EvoStats(
    [
        0.01839779791714692,
        0.017740379737943145,
        0.01875549581305351,
        0.004874207110264391,
        0.001266943643897657,
        0.027778616306906322,
        0.03350941785181738,
    ],
    99,
);

fn evo_pair() -> (Trajectory, Trajectory) {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data");
    let gt = Trajectory::read_tum(&dir.join("evo_gt.txt")).expect("gt file");
    let est = Trajectory::read_tum(&dir.join("evo_est.txt")).expect("est file");
    (gt, est)
}

/// Largest |ours - evo| over the seven statistics; also checks the count.
fn max_diff(ours: &Stats, evo: &EvoStats) -> f64 {
    assert_eq!(ours.count, evo.1, "number of errors");
    let o = [
        ours.rmse,
        ours.mean,
        ours.median,
        ours.std,
        ours.min,
        ours.max,
        ours.sse,
    ];
    o.iter()
        .zip(evo.0)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max)
}

fn config(alignment: Alignment) -> EvalConfig {
    EvalConfig {
        alignment,
        ..EvalConfig::default()
    }
}

#[test]
fn ate_matches_evo_ape() {
    let (gt, est) = evo_pair();
    for (alignment, evo) in [
        (Alignment::None, &APE_NONE),
        (Alignment::Se3, &APE_SE3),
        (Alignment::Sim3, &APE_SIM3),
    ] {
        let result = ate(&gt, &est, &config(alignment)).expect("ate");
        let d = max_diff(&result.stats, evo);
        println!("evo_ape {alignment:?}: max |ours - evo| = {d:.3e}");
        assert!(d < EVO_TOLERANCE, "{alignment:?}: {d}");
    }
}

#[test]
fn rpe_matches_evo_rpe() {
    let (gt, est) = evo_pair();
    let plain = rpe(&gt, &est, &EvalConfig::default()).expect("rpe");
    let sim3 = rpe(&gt, &est, &config(Alignment::Sim3)).expect("rpe sim3");
    for (name, ours, evo) in [
        ("trans_part", &plain.translation, &RPE_TRANS),
        ("angle_deg", &plain.rotation_deg, &RPE_ANGLE_DEG),
        (
            "trans_part --align --correct_scale",
            &sim3.translation,
            &RPE_TRANS_SIM3,
        ),
    ] {
        let d = max_diff(ours, evo);
        println!("evo_rpe {name}: max |ours - evo| = {d:.3e}");
        assert!(d < EVO_TOLERANCE, "{name}: {d}");
    }
    // A rigid alignment leaves relative poses unchanged.
    let se3 = rpe(&gt, &est, &config(Alignment::Se3)).expect("rpe se3");
    assert!(max_diff(&se3.translation, &RPE_TRANS) < EVO_TOLERANCE);
}

#[test]
fn ate_of_a_trajectory_against_itself_is_zero() {
    let gt = room_trajectory_stamped(60);
    for alignment in [Alignment::None, Alignment::Se3, Alignment::Sim3] {
        let r = ate(&gt, &gt, &config(alignment)).expect("ate");
        assert_eq!(r.pairs.len(), 60);
        assert!(
            r.stats.max < EXACT_TOLERANCE,
            "{alignment:?}: {}",
            r.stats.max
        );
        let p = rpe(&gt, &gt, &config(alignment)).expect("rpe");
        assert!(p.translation.max < EXACT_TOLERANCE && p.rotation_deg.max < 1e-6);
    }
}

#[test]
fn degenerate_and_tiny_inputs_are_typed_errors() {
    let line = Trajectory::new(
        (0..10)
            .map(|i| (i as f64, Isometry3::translation(i as f64, 0.0, 0.0)))
            .collect(),
    );
    assert_eq!(
        ate(&line, &line, &config(Alignment::Se3)),
        Err(EvalError::Degenerate)
    );
    let two = Trajectory::new(line.poses[..2].to_vec());
    assert_eq!(
        ate(&two, &two, &config(Alignment::Sim3)),
        Err(EvalError::TooFewPoses(2))
    );
    let mut nan = room_trajectory_stamped(10);
    nan.poses[4].1.translation.vector.y = f64::NAN;
    for alignment in [Alignment::None, Alignment::Se3] {
        assert_eq!(
            ate(&nan, &nan, &config(alignment)),
            Err(EvalError::NotFinite)
        );
    }
    let shifted = Trajectory::new(line.poses.iter().map(|(t, p)| (t + 0.5, *p)).collect());
    assert_eq!(
        rpe(&line, &shifted, &EvalConfig::default()),
        Err(EvalError::TooFewPoses(0))
    );
}

fn room_trajectory_stamped(n: usize) -> Trajectory {
    Trajectory::new(
        room_trajectory(n)
            .into_iter()
            .enumerate()
            .map(|(i, p)| (i as f64 / 30.0, p))
            .collect(),
    )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Points mapped by a known similarity are mapped back exactly.
    #[test]
    fn umeyama_recovers_a_known_similarity(
        axis in prop::array::uniform3(-1.0f64..1.0),
        angle in -3.0f64..3.0,
        shift in prop::array::uniform3(-5.0f64..5.0),
        scale in 0.1f64..10.0,
        seed in 0u64..1000,
    ) {
        let axis = Vector3::from(axis);
        prop_assume!(axis.norm() > 1e-3);
        let rotation = UnitQuaternion::from_scaled_axis(axis.normalize() * angle);
        let translation = Vector3::from(shift);
        let x: Vec<Vector3<f64>> = (0..12)
            .map(|i| {
                let k = (seed + i) as f64;
                Vector3::new((1.3 * k).sin(), (2.1 * k).cos(), (0.7 * k + 0.4).sin()) * 2.0
            })
            .collect();
        let y: Vec<_> = x.iter().map(|p| scale * (rotation * p) + translation).collect();
        let sim = umeyama(&x, &y, true).expect("well-posed");
        prop_assert!((sim.scale - scale).abs() < EXACT_TOLERANCE * scale);
        prop_assert!(sim.rotation.angle_to(&rotation) < EXACT_TOLERANCE);
        prop_assert!((sim.translation - translation).norm() < EXACT_TOLERANCE * 10.0);
        let rigid = umeyama(&x, &x.iter().map(|p| rotation * p + translation).collect::<Vec<_>>(), false)
            .expect("well-posed");
        prop_assert!(rigid.scale == 1.0 && rigid.rotation.angle_to(&rotation) < EXACT_TOLERANCE);
    }
}

#[test]
fn sim3_alignment_undoes_a_similarity_of_the_whole_trajectory() {
    let gt = room_trajectory_stamped(90);
    let s = Isometry3::from_parts(
        Translation3::new(0.3, -1.0, 2.0),
        UnitQuaternion::from_euler_angles(0.4, -0.2, 1.0),
    );
    let est = Trajectory::new(
        gt.poses
            .iter()
            .map(|(t, p)| {
                let mut q = s * p;
                q.translation.vector *= 2.5;
                (*t, q)
            })
            .collect(),
    );
    let r = ate(&gt, &est, &config(Alignment::Sim3)).expect("ate");
    assert!((r.alignment.scale - 1.0 / 2.5).abs() < EXACT_TOLERANCE);
    assert!(r.stats.max < EXACT_TOLERANCE);
    for ((_, q), (_, p)) in gt.poses.iter().zip(&r.aligned.poses) {
        assert!(q.rotation.angle_to(&p.rotation) < EXACT_TOLERANCE);
    }
}

#[test]
fn plot_draws_both_panels() {
    let (gt, est) = evo_pair();
    let r = ate(&gt, &est, &config(Alignment::Sim3)).expect("ate");
    let img = render_plot(&gt, &r.aligned, &r.errors).expect("plot");
    let count = |c| img.pixels().filter(|p| **p == c).count();
    let half = img.width() / 2;
    let left_of = |c| {
        img.enumerate_pixels()
            .filter(|(x, _, p)| **p == c && *x < half)
            .count()
    };
    // Polylines over ~120 poses spanning most of a 420 px plot area: hundreds of pixels each.
    assert!(left_of(GT_COLOUR) > 300 && left_of(EST_COLOUR) > 300);
    assert!(count(ERROR_COLOUR) > 300 && left_of(ERROR_COLOUR) == 0);
    let path = std::env::temp_dir().join(format!("vofront-plot-{}.png", std::process::id()));
    write_plot(&path, &gt, &r.aligned, &r.errors).expect("write");
    assert_eq!(image::open(&path).expect("png").width(), img.width());
    std::fs::remove_file(&path).expect("cleanup");
    assert!(render_plot(&gt, &r.aligned, &[]).is_err());
}
