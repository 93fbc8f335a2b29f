//! Trajectory evaluation against the `evo` package, Umeyama recovery, and the plot writer.

use std::path::Path;

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use proptest::prelude::*;
use vofront::eval::plot::{render_plot, write_plot, ERROR_COLOUR, EST_COLOUR, GT_COLOUR};
use vofront::eval::plot::{write_eval_plots, PlotFormat};
use vofront::eval::{
    ate, rpe, rpe_with, umeyama, Alignment, DeltaUnit, EvalConfig, EvalError, RpeConfig, Stats,
};
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

// evo v1.38.1 on the same pair, `evo_rpe tum evo_gt.txt evo_est.txt --delta D --delta_unit U
// [--all_pairs] [--pairs_from_reference] [--align --correct_scale] --pose_relation R
// --no_warnings --save_results r.zip`, statistics from `stats.json`, count from
// `error_array.npy`. Each entry: (delta, unit, all_pairs, pairs_from_reference, sim3,
// relation is angle_deg, evo's numbers).
type EvoRpeCase = (f64, DeltaUnit, bool, bool, bool, bool, EvoStats);
const EVO_RPE_DELTAS: [EvoRpeCase; 12] = [
    (
        10.0,
        DeltaUnit::Frames,
        false,
        false,
        false,
        false,
        EvoStats(
            [
                0.04105108457052664,
                0.03792117896206341,
                0.04179772478511641,
                0.01572182338482689,
                0.016007986322204588,
                0.06122622068554926,
                0.015166723899748772,
            ],
            9,
        ),
    ),
    (
        10.0,
        DeltaUnit::Frames,
        false,
        false,
        false,
        true,
        EvoStats(
            [
                0.8360983208538076,
                0.7764813331490825,
                0.8207805956700424,
                0.3100598997058154,
                0.37706969797725426,
                1.3042937667034555,
                6.29154361921101,
            ],
            9,
        ),
    ),
    (
        10.0,
        DeltaUnit::Frames,
        true,
        false,
        false,
        false,
        EvoStats(
            [
                0.03926079949467537,
                0.03691184498203685,
                0.03827166973954384,
                0.013376325242127706,
                0.004869366821036544,
                0.0642874511120505,
                0.13872693392649915,
            ],
            90,
        ),
    ),
    (
        10.0,
        DeltaUnit::Frames,
        true,
        false,
        false,
        true,
        EvoStats(
            [
                0.8604627813021865,
                0.814159437466871,
                0.8711056845020695,
                0.2784611434112893,
                0.21816080727248702,
                1.3219515799915105,
                66.6356578205665,
            ],
            90,
        ),
    ),
    (
        10.0,
        DeltaUnit::Frames,
        true,
        false,
        true,
        false,
        EvoStats(
            [
                0.018664660006435126,
                0.017854432756973352,
                0.018785491557062862,
                0.00543955550413229,
                0.002887260592774372,
                0.028232290640991427,
                0.031353257984023705,
            ],
            90,
        ),
    ),
    (
        0.2,
        DeltaUnit::Meters,
        false,
        false,
        false,
        false,
        EvoStats(
            [
                0.053909059234582606,
                0.05180544264918028,
                0.05575122278877875,
                0.014912504131775778,
                0.03071762504340163,
                0.07035764082700184,
                0.02034330667290415,
            ],
            7,
        ),
    ),
    (
        0.2,
        DeltaUnit::Meters,
        false,
        false,
        false,
        true,
        EvoStats(
            [
                0.7147324590176545,
                0.6626840646607549,
                0.5407934185738148,
                0.2677542126991164,
                0.3372624914854031,
                1.1268199133876073,
                3.5758974158139623,
            ],
            7,
        ),
    ),
    (
        0.2,
        DeltaUnit::Meters,
        true,
        false,
        false,
        false,
        EvoStats(
            [
                0.04949335914621084,
                0.04726543462636866,
                0.048752930652815954,
                0.014682346173424805,
                0.01414498485395773,
                0.075025691965253,
                0.2131145561630957,
            ],
            87,
        ),
    ),
    (
        0.2,
        DeltaUnit::Meters,
        true,
        false,
        false,
        true,
        EvoStats(
            [
                0.8498877480262711,
                0.7987015397845069,
                0.8478743391544759,
                0.29049102325377385,
                0.2432072719740132,
                1.5081218601630764,
                62.840899029329485,
            ],
            87,
        ),
    ),
    (
        0.2,
        DeltaUnit::Meters,
        false,
        true,
        false,
        false,
        EvoStats(
            [
                0.06247970684763892,
                0.06103647853549214,
                0.06544811601824224,
                0.013351481406694288,
                0.037943368729395736,
                0.075025691965253,
                0.019518568838834488,
            ],
            5,
        ),
    ),
    (
        0.2,
        DeltaUnit::Meters,
        false,
        false,
        true,
        false,
        EvoStats(
            [
                0.019252392333492237,
                0.018257792035982285,
                0.019466441841638614,
                0.006107998079038059,
                0.007387676974627583,
                0.025248662784710933,
                0.0033358914950643967,
            ],
            9,
        ),
    ),
    (
        0.2,
        DeltaUnit::Meters,
        true,
        false,
        true,
        false,
        EvoStats(
            [
                0.016805283475102673,
                0.015625493520332094,
                0.016950171951416706,
                0.006185588486524048,
                0.0012257032547348978,
                0.028327973010436873,
                0.025135162188391756,
            ],
            89,
        ),
    ),
];

/// Agreement required with evo's RPE over deltas (the bound).
const EVO_DELTA_TOLERANCE: f64 = 1e-9;

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
fn rpe_over_deltas_matches_evo_rpe() {
    let (gt, est) = evo_pair();
    for (delta, unit, all_pairs, pairs_from_reference, sim3, angle, evo) in &EVO_RPE_DELTAS {
        let alignment = if *sim3 {
            Alignment::Sim3
        } else {
            Alignment::None
        };
        let pairs = RpeConfig {
            delta: *delta,
            unit: *unit,
            all_pairs: *all_pairs,
            pairs_from_reference: *pairs_from_reference,
            ..RpeConfig::default()
        };
        let r = rpe_with(&gt, &est, &config(alignment), &pairs).expect("rpe");
        let ours = if *angle {
            &r.rotation_deg
        } else {
            &r.translation
        };
        let d = max_diff(ours, evo);
        println!("evo_rpe {pairs:?} sim3 {sim3} angle {angle}: max |ours - evo| = {d:.3e}");
        assert!(
            d < EVO_DELTA_TOLERANCE,
            "{pairs:?} sim3 {sim3} angle {angle}: {d}"
        );
        assert_eq!(r.delta_pairs.len(), r.times.len());
    }
}

/// A constant-velocity trajectory at 30 Hz, 0.01 m per frame: a delta of 10 frames, 0.1 m
/// and 1/3 s select the same pairs.
#[test]
fn frames_metres_and_seconds_agree_on_uniform_motion() {
    let gt = Trajectory::new(
        (0..61)
            .map(|i| {
                (
                    i as f64 / 30.0,
                    Isometry3::translation(0.01 * i as f64, 0.0, 0.0),
                )
            })
            .collect(),
    );
    // A drifting estimate so that the errors are not all zero.
    let est = Trajectory::new(
        gt.poses
            .iter()
            .map(|(t, p)| (*t, Isometry3::rotation(Vector3::y() * (0.3 * t)) * p))
            .collect(),
    );
    let run = |delta: f64, unit: DeltaUnit, all_pairs: bool| {
        let c = RpeConfig {
            delta,
            unit,
            all_pairs,
            pairs_from_reference: true,
            // Less than one frame's worth (0.01 m, 1/30 s) of miss, unlike evo's default 0.1.
            delta_tol: 0.05,
        };
        rpe_with(&gt, &est, &EvalConfig::default(), &c).expect("rpe")
    };
    for all_pairs in [false, true] {
        let frames = run(10.0, DeltaUnit::Frames, all_pairs);
        // Slightly under the nominal spacing so that rounding cannot skip a frame.
        let metres = run(0.1 - 1e-9, DeltaUnit::Meters, all_pairs);
        let seconds = run(10.0 / 30.0 - 1e-9, DeltaUnit::Seconds, all_pairs);
        assert_eq!(frames.delta_pairs.len(), if all_pairs { 51 } else { 6 });
        assert_eq!(
            frames.delta_pairs, metres.delta_pairs,
            "all_pairs {all_pairs}"
        );
        assert_eq!(
            frames.delta_pairs, seconds.delta_pairs,
            "all_pairs {all_pairs}"
        );
        assert!(frames.translation.max > 1e-3);
    }
}

#[test]
fn bad_deltas_and_tolerances_are_typed_errors() {
    let (gt, est) = evo_pair();
    for (delta, unit) in [
        (0.0, DeltaUnit::Frames),
        (2.5, DeltaUnit::Frames),
        (-1.0, DeltaUnit::Meters),
        (f64::NAN, DeltaUnit::Seconds),
    ] {
        let c = RpeConfig {
            delta,
            unit,
            ..RpeConfig::default()
        };
        assert!(matches!(
            rpe_with(&gt, &est, &EvalConfig::default(), &c),
            Err(EvalError::BadDelta(_))
        ));
    }
    let far = RpeConfig {
        delta: 1000.0,
        unit: DeltaUnit::Meters,
        ..RpeConfig::default()
    };
    assert!(matches!(
        rpe_with(&gt, &est, &EvalConfig::default(), &far),
        Err(EvalError::NoPairs(_))
    ));
    let negative = EvalConfig {
        max_dt: -1.0,
        ..EvalConfig::default()
    };
    assert_eq!(ate(&gt, &est, &negative), Err(EvalError::BadMaxDt(-1.0)));
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
    #![proptest_config(ProptestConfig::with_cases(vofront_fixtures::proptest_cases(64)))]

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
    // Polylines over ~100 poses spanning most of a 480 px plot area: at least a pixel per pose.
    println!(
        "gt {} est {} error {}",
        left_of(GT_COLOUR),
        left_of(EST_COLOUR),
        count(ERROR_COLOUR)
    );
    assert!(left_of(GT_COLOUR) > 100 && left_of(EST_COLOUR) > 100);
    assert!(count(ERROR_COLOUR) > 100 && left_of(ERROR_COLOUR) == 0);
    let path = std::env::temp_dir().join(format!("vofront-plot-{}.png", std::process::id()));
    write_plot(&path, &gt, &r.aligned, &r.errors).expect("write");
    assert_eq!(image::open(&path).expect("png").width(), img.width());
    std::fs::remove_file(&path).expect("cleanup");
    assert!(render_plot(&gt, &r.aligned, &[]).is_err());
}

#[test]
fn every_eval_figure_is_written_as_png_and_svg() {
    let (gt, est) = evo_pair();
    let a = ate(&gt, &est, &config(Alignment::Se3)).expect("ate");
    let r = rpe(&gt, &est, &EvalConfig::default()).expect("rpe");
    let dir = std::env::temp_dir().join(format!("vofront-eval-plots-{}", std::process::id()));
    let pngs = write_eval_plots(&dir, PlotFormat::Png, &gt, &a, &r).expect("png");
    let svgs = write_eval_plots(&dir, PlotFormat::Svg, &gt, &a, &r).expect("svg");
    assert_eq!(pngs.len(), 5);
    for p in &pngs {
        let img = image::open(p).expect("png").to_rgb8();
        // Not blank: the plotted series leave many non-white pixels.
        assert!(
            img.pixels().filter(|px| px.0 != [255, 255, 255]).count() > 2000,
            "{}",
            p.display()
        );
    }
    for p in &svgs {
        let text = std::fs::read_to_string(p).expect("svg");
        // Axis names are text in the SVG.
        assert!(
            text.starts_with("<svg") && text.contains("(m)"),
            "{}",
            p.display()
        );
    }
    std::fs::remove_dir_all(&dir).expect("cleanup");
}

/// Runs the `vofront` binary in `dir`.
fn vofront(args: &[&str], dir: &Path) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_vofront"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("run vofront")
}

#[test]
fn eval_command_takes_evo_style_deltas_and_prints_json() {
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data");
    let out = vofront(
        &[
            "eval",
            "evo_gt.txt",
            "evo_est.txt",
            "--align",
            "none",
            "--delta",
            "10",
            "--delta_unit",
            "f",
            "--all_pairs",
            "--json",
        ],
        &data,
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON object");
    let evo = &EVO_RPE_DELTAS[2].6; // --delta 10 --delta_unit f --all_pairs, trans_part
    let rmse = json["rpe"]["translation"]["rmse"].as_f64().expect("rmse");
    assert!((rmse - evo.0[0]).abs() < EVO_DELTA_TOLERANCE, "{json}");
    assert_eq!(json["rpe"]["pairs"], 90);
    assert_eq!(json["rpe"]["delta_unit"], "frames");
    assert_eq!(json["alignment"], "none");
}

/// Negative numbers are values, not flags; a bad value is a one-line job error (exit 1).
#[test]
fn negative_numbers_reach_the_value_checks() {
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data");
    let out = vofront(
        &["eval", "evo_gt.txt", "evo_est.txt", "--max-dt", "-1"],
        &data,
    );
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("-1 s is invalid"));
    for args in [
        ["--dist", "-0.28,0.07,0,0"],
        ["--fx", "-500"],
        ["--cx", "-3.5"],
    ] {
        let mut all = vec!["two-view", "missing1.png", "missing2.png"];
        all.extend(args);
        let out = vofront(&all, &data);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
        assert!(!err.contains("unexpected argument"), "{args:?}: {err}");
    }
}
