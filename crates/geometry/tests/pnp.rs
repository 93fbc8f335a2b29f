//! P3P and the robust PnP pipeline on random scenes.

mod common;

use nalgebra::{Isometry3, Matrix3, Point3, Vector2, Vector3};
use proptest::prelude::*;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use vofront_geometry::camera::{Camera, Distortion, Pinhole};
use vofront_geometry::p3p::p3p;
use vofront_geometry::pnp::{
    add_point_covariances, solve_pnp_ransac, solve_pnp_ransac_with_point_covariances,
    solve_pnp_ransac_with_sigmas, PnpConfig,
};
use vofront_geometry::GeometryError;
use vofront_geometry::RansacConfig;

/// TUM fr1 lens: the refinement must model the distortion.
fn distorted_camera() -> Camera {
    Camera::new(
        Pinhole::new(517.3, 516.5, 318.6, 255.3).unwrap(),
        Distortion::from_array([0.2624, -0.9531, -0.0054, 0.0026, 1.1633]),
    )
}

/// `(T_cw, world points, pixels, is_inlier)`.
type PnpScene = (
    Isometry3<f64>,
    Vec<Point3<f64>>,
    Vec<Vector2<f64>>,
    Vec<bool>,
);

/// World points in front of the camera `T_cw` and their pixels (noise `sigma`, the first
/// `outlier_ratio` of them replaced by random pixels).
fn pnp_scene(seed: u64, n: usize, outlier_ratio: f64, sigma: f64, cam: &Camera) -> PnpScene {
    let mut rng = StdRng::seed_from_u64(seed);
    let t_cw = common::random_pose(&mut rng, 0.5, 1.0);
    let t_wc = t_cw.inverse();
    let (mut world, mut px, mut inl) = (vec![], vec![], vec![]);
    while world.len() < n {
        let x: f64 = rng.random_range(-0.5..0.5);
        let y: f64 = rng.random_range(-0.4..0.4);
        let z: f64 = rng.random_range(2.0..8.0);
        let pc = Point3::new(x * z, y * z, z);
        let Some(u) = cam.project(&pc.coords) else {
            continue;
        };
        let outlier = (world.len() as f64) < outlier_ratio * n as f64;
        let u = if outlier {
            Vector2::new(rng.random_range(0.0..640.0), rng.random_range(0.0..480.0))
        } else {
            u + Vector2::new(common::gauss(&mut rng), common::gauss(&mut rng)) * sigma
        };
        world.push(t_wc * pc);
        px.push(u);
        inl.push(!outlier);
    }
    (t_cw, world, px, inl)
}

/// Exact-data P3P tolerance on `T_cw` (4x4 entries). The depths are Newton-polished on the
/// distance constraints, so a well-conditioned triple comes out to 1e-10 or better (two of
/// three points 7 cm apart at 5 m, seed 588063: 5e-10, the same as absolute orientation from
/// the exact depths); near the danger cylinder two solutions merge, the constraints'
/// Jacobian is nearly singular and only about half of the double-precision digits survive.
const P3P_TOL: f64 = 1e-5;

/// Pose bounds for 100 points at 0.5 px noise (rotation degrees, translation metres for a
/// scene 2-8 m deep, 50-100 inliers): about twice the worst seen over many seeds (0.12
/// degrees, 1 cm).
const ROT_BOUND_DEG: f64 = 0.25;
const TRANS_BOUND_M: f64 = 0.05;

proptest! {
    #![proptest_config(ProptestConfig::with_cases(vofront_fixtures::proptest_cases(48)))]

    #[test]
    fn p3p_contains_the_true_pose(seed in 0u64..1_000_000) {
        let cam = common::camera();
        let (t_cw, world, px, _) = pnp_scene(seed, 3, 0.0, 0.0, &cam);
        let f: [Vector3<f64>; 3] = std::array::from_fn(|i| cam.bearing(&px[i]).unwrap().into_inner());
        let w = [world[0], world[1], world[2]];
        let mut sols = Vec::new();
        p3p(&w, &f, &mut sols);
        prop_assert!(sols.len() <= 4);
        let err = sols.iter().map(|s| (s.to_homogeneous() - t_cw.to_homogeneous()).norm()).fold(f64::INFINITY, f64::min);
        prop_assert!(err < P3P_TOL, "{}", err);
    }

    #[test]
    fn pnp_recovers_pose_with_outliers_and_distortion(seed in 0u64..1_000_000, outliers in 0.0f64..0.5) {
        let cam = distorted_camera();
        let (t_cw, world, px, inl) = pnp_scene(seed, 100, outliers, 0.5, &cam);
        let res = solve_pnp_ransac(&world, &px, &cam, None, &PnpConfig::default()).unwrap();
        let rot = res.pose.rotation.angle_to(&t_cw.rotation).to_degrees();
        let trans = (res.pose.translation.vector - t_cw.translation.vector).norm();
        prop_assert!(rot < ROT_BOUND_DEG && trans < TRANS_BOUND_M, "rot {} trans {}", rot, trans);
        let false_in = res.inliers.iter().zip(&inl).filter(|(a, b)| **a && !**b).count();
        prop_assert!(false_in <= 3);
        prop_assert!(res.rmse_px < 1.0);
        // The covariance is a positive definite quality score.
        prop_assert!(res.covariance.and_then(|c| c.cholesky()).is_some());
    }
}

#[test]
fn covariance_grows_with_noise() {
    let cam = common::camera();
    let trace = |sigma: f64| {
        let (_, world, px, _) = pnp_scene(11, 100, 0.0, sigma, &cam);
        solve_pnp_ransac(
            &world,
            &px,
            &cam,
            None,
            &PnpConfig {
                ransac: RansacConfig {
                    threshold: 4.0,
                    ..PnpConfig::default().ransac
                },
                ..Default::default()
            },
        )
        .unwrap()
        .covariance
        .expect("a refined pose has a known covariance")
        .trace()
    };
    assert!(trace(1.0) > 2.0 * trace(0.3));
}

/// `(e_phi^T C_phi^-1 e_phi, e_rho^T C_rho^-1 e_rho)`: the rotation and translation blocks'
/// NEES of `fit` against the true `t_cw`, the error being the left increment
/// `delta = log(T_true T_est^-1) = (rho, phi)` of the covariance's convention.
fn nees_blocks(fit: &vofront_geometry::PnpResult, t_cw: &Isometry3<f64>) -> (f64, f64) {
    let cov = fit.covariance.expect("a refined pose has a covariance");
    let delta = vofront_geometry::lie::se3_log(&(t_cw * fit.pose.inverse()));
    let block = |k: usize| {
        let e = delta.fixed_rows::<3>(k).into_owned();
        let c = cov.fixed_view::<3, 3>(k, k).into_owned();
        e.dot(&(c.try_inverse().expect("invertible block") * e))
    };
    (block(3), block(0))
}

/// Mean NEES over its 3 degrees of freedom of the rotation and of the translation block of
/// PnP's covariance over 200 scenes (80 points, 10% outliers, the TUM lens) at pixel noise
/// `sigma`, with the inlier threshold at 4 sigma. The error is the left increment
/// `delta = log(T_true T_est^-1) = (rho, phi)` of the covariance's convention.
fn pnp_nees(sigma: f64) -> (f64, f64) {
    const SEEDS: u64 = 200;
    let cam = distorted_camera();
    let cfg = PnpConfig {
        ransac: RansacConfig {
            threshold: 4.0 * sigma,
            ..PnpConfig::default().ransac
        },
        ..Default::default()
    };
    let (mut rot, mut trans) = (0.0, 0.0);
    for seed in 0..SEEDS {
        let (t_cw, world, px, _) = pnp_scene(7000 + seed, 80, 0.1, sigma, &cam);
        let fit = solve_pnp_ransac(&world, &px, &cam, None, &cfg).unwrap();
        let (r, t) = nees_blocks(&fit, &t_cw);
        trans += t;
        rot += r;
    }
    (rot / (3.0 * SEEDS as f64), trans / (3.0 * SEEDS as f64))
}

#[test]
fn covariance_is_calibrated_at_known_pixel_noise() {
    for sigma in [0.5, 1.0, 2.0] {
        let (rot, trans) = pnp_nees(sigma);
        eprintln!("noise {sigma} px: mean NEES/dof rotation {rot:.3}, translation {trans:.3}");
        for (name, m) in [("rotation", rot), ("translation", trans)] {
            assert!(
                (0.7..=1.5).contains(&m),
                "noise {sigma} px: {name} NEES/dof {m}"
            );
        }
    }
}

/// `world` with stereo-like depth noise: each point moved along its ray from the camera
/// `reference` (world pose) by a relative `sigma_z / z` of `relative_sigma` (seeded), and that
/// noise's covariance `relative_sigma^2 ray ray^T`.
fn depth_noise(
    world: &[Point3<f64>],
    reference: &Isometry3<f64>,
    relative_sigma: f64,
    seed: u64,
) -> (Vec<Point3<f64>>, Vec<Option<Matrix3<f64>>>) {
    let mut rng = StdRng::seed_from_u64(seed);
    world
        .iter()
        .map(|p| {
            let ray = p.coords - reference.translation.vector;
            let shift = ray * (relative_sigma * common::gauss(&mut rng));
            let c = ray * ray.transpose() * relative_sigma.powi(2);
            (Point3::from(p.coords + shift), Some(c))
        })
        .unzip()
}

/// PnP at 0.5 px pixel noise with a threshold wide enough for the points' depth noise.
fn point_noise_config() -> PnpConfig {
    PnpConfig {
        ransac: RansacConfig {
            threshold: 8.0,
            ..PnpConfig::default().ransac
        },
        sigma_px: 0.5,
        ..Default::default()
    }
}

/// Mean NEES per degree of freedom of the rotation and translation blocks over 200 scenes
/// whose 80 points carry stereo-like depth noise (relative `sigma_Z / Z` of 2% along their
/// ray from a reference camera 1 m behind, as a keyframe's stereo points seen from the next
/// frame) and 0.5 px pixel noise: PnP's own covariance, and the covariance raised by the
/// points' covariances ([`add_point_covariances`], at the true pixel noise). Also checks on
/// every scene that raising never lowers a sigma, in the covariance or in the quality record.
fn pnp_nees_with_point_noise() -> [(f64, f64); 2] {
    const SEEDS: u64 = 200;
    const RELATIVE_DEPTH_SIGMA: f64 = 0.02;
    let cam = distorted_camera();
    let cfg = point_noise_config();
    let mut sums = [(0.0, 0.0); 2];
    for seed in 0..SEEDS {
        let (t_cw, world, px, _) = pnp_scene(9000 + seed, 80, 0.0, 0.5, &cam);
        let reference = t_cw.inverse() * Isometry3::translation(0.0, 0.0, -1.0);
        let (noisy, covariances) = depth_noise(&world, &reference, RELATIVE_DEPTH_SIGMA, seed);
        let fit = solve_pnp_ransac(&noisy, &px, &cam, None, &cfg).unwrap();
        let mut raised = fit.clone();
        let sigmas = vec![1.0; noisy.len()];
        add_point_covariances(&mut raised, &cam, &noisy, &sigmas, &covariances, &cfg);
        let (own, wide) = (fit.covariance.unwrap(), raised.covariance.unwrap());
        assert!((wide - own).symmetric_eigen().eigenvalues.min() > -1e-12);
        let sigma = |f: &vofront_geometry::PnpResult| {
            let u = &f.quality.uncertainty;
            (
                u.rotation_sigma_deg.unwrap(),
                u.translation_sigma_m.unwrap(),
            )
        };
        let (s_own, s_wide) = (sigma(&fit), sigma(&raised));
        assert!(s_wide.0 >= s_own.0 * (1.0 - 1e-9) && s_wide.1 >= s_own.1 * (1.0 - 1e-9));
        for (sum, fit) in sums.iter_mut().zip([&fit, &raised]) {
            let (r, t) = nees_blocks(fit, &t_cw);
            sum.0 += r / (3.0 * SEEDS as f64);
            sum.1 += t / (3.0 * SEEDS as f64);
        }
    }
    sums
}

/// With independent point noise PnP's empirical covariance sees it in the residuals and is
/// calibrated; raised by the points' covariances it stays calibrated (it claims no less than
/// the model, and not much more), while every sigma is at least PnP's own.
#[test]
fn point_covariances_raise_the_pose_covariance_and_keep_it_calibrated() {
    let [own, raised] = pnp_nees_with_point_noise();
    eprintln!("NEES/dof (rotation, translation): PnP's own {own:?}, raised {raised:?}");
    for m in [own.0, own.1, raised.0, raised.1] {
        assert!((0.7..=1.5).contains(&m), "own {own:?}, raised {raised:?}");
    }
    assert!(raised.0 < own.0 && raised.1 < own.1);
}

/// Squared pose errors (rotation rad^2, translation m^2) and mean NEES per dof (rotation,
/// translation) over 150 scenes whose 80 points carry stereo-like depth noise (relative
/// `sigma_Z / Z` of 5% along their ray from a reference camera 1 m behind and 0.5 m to the
/// side) and 0.5 px pixel noise: PnP weighing each pixel alone ([`solve_pnp_ransac_with_sigmas`]),
/// and weighing each residual by its point's covariance too
/// ([`solve_pnp_ransac_with_point_covariances`]).
fn pnp_errors_with_point_noise() -> [(f64, f64, f64, f64); 2] {
    const SEEDS: u64 = 150;
    const RELATIVE_DEPTH_SIGMA: f64 = 0.05;
    let cam = distorted_camera();
    let cfg = point_noise_config();
    let mut sums = [(0.0, 0.0, 0.0, 0.0); 2];
    for seed in 0..SEEDS {
        let (t_cw, world, px, _) = pnp_scene(7000 + seed, 80, 0.0, 0.5, &cam);
        let reference = t_cw.inverse() * Isometry3::translation(0.5, 0.0, -1.0);
        let (noisy, covariances) = depth_noise(&world, &reference, RELATIVE_DEPTH_SIGMA, seed);
        let sigmas = vec![1.0; noisy.len()];
        let pixel_only = solve_pnp_ransac_with_sigmas(&noisy, &px, &sigmas, &cam, None, &cfg);
        let weighed = solve_pnp_ransac_with_point_covariances(
            &noisy,
            &px,
            &sigmas,
            &covariances,
            &cam,
            None,
            &cfg,
        );
        for (sum, fit) in sums.iter_mut().zip([pixel_only.unwrap(), weighed.unwrap()]) {
            let delta = vofront_geometry::lie::se3_log(&(t_cw * fit.pose.inverse()));
            let (r, t) = nees_blocks(&fit, &t_cw);
            let n = SEEDS as f64;
            sum.0 += delta.fixed_rows::<3>(3).norm_squared() / n;
            sum.1 += delta.fixed_rows::<3>(0).norm_squared() / n;
            sum.2 += r / (3.0 * n);
            sum.3 += t / (3.0 * n);
        }
    }
    sums
}

/// Weighing each residual by its point's depth noise (a first-order marginalisation of the
/// depth) lowers both the rotation and the translation error against weighing the pixels
/// alone, and its own covariance stays calibrated (mean NEES per dof in [0.7, 1.5]).
#[test]
fn point_covariances_weigh_the_refinement() {
    let [pixel_only, weighed] = pnp_errors_with_point_noise();
    eprintln!("(rot err^2, trans err^2, NEES rot, NEES trans): pixels alone {pixel_only:?}, weighed {weighed:?}");
    assert!(weighed.0 < 0.8 * pixel_only.0, "{pixel_only:?} {weighed:?}");
    assert!(weighed.1 < 0.8 * pixel_only.1, "{pixel_only:?} {weighed:?}");
    for nees in [weighed.2, weighed.3] {
        assert!((0.7..=1.5).contains(&nees), "{weighed:?}");
    }
}

/// Without a point covariance the weighed solve is the pixel-only one; covariances that are not
/// index-aligned or not finite are typed errors.
#[test]
fn point_covariances_are_checked_and_none_changes_nothing() {
    let cam = distorted_camera();
    let (_, world, px, _) = pnp_scene(41, 60, 0.2, 0.5, &cam);
    let sigmas = vec![1.0; px.len()];
    let cfg = PnpConfig::default();
    let plain = solve_pnp_ransac_with_sigmas(&world, &px, &sigmas, &cam, None, &cfg).unwrap();
    let none = vec![None; px.len()];
    let same =
        solve_pnp_ransac_with_point_covariances(&world, &px, &sigmas, &none, &cam, None, &cfg)
            .unwrap();
    assert_eq!(plain.pose, same.pose);
    assert_eq!(plain.inliers, same.inliers);
    assert_eq!(plain.covariance, same.covariance);
    assert!(matches!(
        solve_pnp_ransac_with_point_covariances(&world, &px, &sigmas, &none[1..], &cam, None, &cfg),
        Err(GeometryError::LengthMismatch(..))
    ));
    let mut bad = none.clone();
    bad[3] = Some(Matrix3::identity() * f64::NAN);
    assert!(matches!(
        solve_pnp_ransac_with_point_covariances(&world, &px, &sigmas, &bad, &cam, None, &cfg),
        Err(GeometryError::NonFinite)
    ));
}

#[test]
fn prior_is_used_when_it_is_the_best_hypothesis() {
    let cam = common::camera();
    let (t_cw, world, px, _) = pnp_scene(5, 50, 0.0, 0.0, &cam);
    let cfg = PnpConfig {
        ransac: RansacConfig {
            max_iterations: 1,
            ..PnpConfig::default().ransac
        },
        refine: false,
        ..Default::default()
    };
    let res = solve_pnp_ransac(&world, &px, &cam, Some(t_cw), &cfg).unwrap();
    assert!((res.pose.to_homogeneous() - t_cw.to_homogeneous()).norm() < 1e-6);
    assert_eq!(res.inlier_count(), 50);
}

/// A wrong prior is only the first hypothesis: the sampled pose beats it, on every scene.
#[test]
fn a_wrong_prior_loses_to_the_sampled_pose() {
    let cam = common::camera();
    for seed in 0..20 {
        let (t_cw, world, px, _) = pnp_scene(seed, 80, 0.3, 0.5, &cam);
        let wrong =
            Isometry3::new(Vector3::new(0.3, 0.0, -0.2), Vector3::new(0.0, 0.35, 0.0)) * t_cw;
        let cfg = PnpConfig::default();
        let with_prior = solve_pnp_ransac(&world, &px, &cam, Some(wrong), &cfg).unwrap();
        let without = solve_pnp_ransac(&world, &px, &cam, None, &cfg).unwrap();
        let (e_prior, e_none) = (
            pose_error(&t_cw, &with_prior.pose),
            pose_error(&t_cw, &without.pose),
        );
        assert!(e_prior < 0.5, "seed {seed}: {e_prior} from the wrong prior");
        assert!(
            (e_prior - e_none).abs() < 0.05,
            "seed {seed}: {e_prior} vs {e_none}"
        );
        assert!(with_prior.inlier_count() >= 50, "seed {seed}");
    }
}

/// The pose found before, given back as the prior, is at the refinement's optimum: local
/// optimisation reproduces it up to rounding, which confirms it, and the search stops at the
/// minimum instead of running to the cap.
#[test]
fn a_located_prior_ends_the_search_at_the_minimum() {
    let cam = common::camera();
    let cfg = PnpConfig::default();
    for seed in 0..10 {
        let (_, world, px, _) = pnp_scene(seed, 120, 0.2, 0.7, &cam);
        let first = solve_pnp_ransac(&world, &px, &cam, None, &cfg).unwrap();
        let again = solve_pnp_ransac(&world, &px, &cam, Some(first.pose), &cfg).unwrap();
        assert_eq!(again.iterations, cfg.ransac.min_iterations, "seed {seed}");
        assert_eq!(again.inlier_count(), first.inlier_count(), "seed {seed}");
    }
}

#[test]
fn pnp_bad_input_gives_typed_errors() {
    let cam = common::camera();
    let (_, world, px, _) = pnp_scene(2, 20, 0.0, 0.5, &cam);
    let cfg = PnpConfig::default();
    assert_eq!(
        solve_pnp_ransac(&world[..3], &px[..3], &cam, None, &cfg),
        Err(GeometryError::TooFewCorrespondences { got: 3, need: 4 })
    );
    let mut nan = px.clone();
    nan[0].y = f64::NAN;
    assert_eq!(
        solve_pnp_ransac(&world, &nan, &cam, None, &cfg),
        Err(GeometryError::NonFinite)
    );
    let same = vec![world[0]; 20];
    assert!(matches!(
        solve_pnp_ransac(&same, &px, &cam, None, &cfg),
        Err(GeometryError::Degenerate(_))
    ));
    let zero_f = Camera::pinhole(Pinhole {
        fx: 520.0,
        fy: 0.0,
        cx: 320.0,
        cy: 240.0,
    });
    assert!(matches!(
        solve_pnp_ransac(&world, &px, &zero_f, None, &cfg),
        Err(GeometryError::Camera(_))
    ));
    let shuffled: Vec<Vector2<f64>> = px.iter().rev().copied().collect();
    // Random matches: an error, or a pose that claims the support of only a few matches
    // (never a confident wrong pose).
    match solve_pnp_ransac(&world, &shuffled, &cam, None, &cfg) {
        Err(_) => {}
        Ok(res) => assert!(
            res.inlier_count() <= world.len() / 2,
            "{} of {} random matches called inliers",
            res.inlier_count(),
            world.len()
        ),
    }
}

/// Pose error of `T_cw` against the truth: rotation (degrees) plus translation (metres) as
/// one figure, for comparisons of two estimates of the same scene.
fn pose_error(truth: &Isometry3<f64>, est: &Isometry3<f64>) -> f64 {
    let d = truth * est.inverse();
    d.rotation.angle().to_degrees() + d.translation.vector.norm()
}

/// Half of the measurements four times noisier than the rest (ORB keypoints two or three
/// pyramid levels up): told their noise scales, PnP weights them down, and over 60 scenes its
/// pose is closer to the truth than with equal weights.
#[test]
fn noise_scales_weight_the_noisier_measurements_down() {
    let cam = common::camera();
    let cfg = PnpConfig {
        ransac: RansacConfig {
            threshold: 12.0,
            ..PnpConfig::default().ransac
        },
        ..Default::default()
    };
    let (mut weighted, mut equal) = (0.0, 0.0);
    for seed in 0..60 {
        let (t_cw, world, mut px, _) = pnp_scene(900 + seed, 60, 0.0, 0.5, &cam);
        let mut rng = StdRng::seed_from_u64(seed);
        let sigmas: Vec<f64> = (0..px.len())
            .map(|k| if k % 2 == 0 { 4.0 } else { 1.0 })
            .collect();
        for (u, s) in px.iter_mut().zip(&sigmas) {
            *u += Vector2::new(common::gauss(&mut rng), common::gauss(&mut rng)) * 0.5 * (s - 1.0);
        }
        let scaled = solve_pnp_ransac_with_sigmas(&world, &px, &sigmas, &cam, None, &cfg).unwrap();
        let plain = solve_pnp_ransac(&world, &px, &cam, None, &cfg).unwrap();
        assert_eq!(scaled.inlier_count(), 60, "seed {seed}");
        weighted += pose_error(&t_cw, &scaled.pose);
        equal += pose_error(&t_cw, &plain.pose);
    }
    assert!(
        weighted < 0.8 * equal,
        "weighted {weighted}, equal weights {equal}"
    );
}

/// The inlier threshold is `threshold * sigma`: a measurement 5 px off is an outlier at the
/// 3 px threshold with scale 1 and an inlier with scale 2; unit scales give exactly
/// `solve_pnp_ransac`.
#[test]
fn the_inlier_threshold_follows_the_noise_scale() {
    let cam = common::camera();
    let (_, world, mut px, _) = pnp_scene(31, 40, 0.0, 0.0, &cam);
    px[0].x += 5.0;
    let cfg = PnpConfig {
        ransac: RansacConfig {
            threshold: 3.0,
            ..PnpConfig::default().ransac
        },
        ..Default::default()
    };
    let mut sigmas = vec![1.0; px.len()];
    let unit = solve_pnp_ransac_with_sigmas(&world, &px, &sigmas, &cam, None, &cfg).unwrap();
    assert_eq!(
        unit,
        solve_pnp_ransac(&world, &px, &cam, None, &cfg).unwrap()
    );
    assert!(!unit.inliers[0] && unit.inlier_count() == 39);
    sigmas[0] = 2.0;
    let scaled = solve_pnp_ransac_with_sigmas(&world, &px, &sigmas, &cam, None, &cfg).unwrap();
    assert!(scaled.inliers[0] && scaled.inlier_count() == 40);
    // Bad scales are typed errors.
    sigmas[0] = 0.0;
    assert!(matches!(
        solve_pnp_ransac_with_sigmas(&world, &px, &sigmas, &cam, None, &cfg),
        Err(GeometryError::InvalidConfig(_))
    ));
    assert_eq!(
        solve_pnp_ransac_with_sigmas(&world, &px, &sigmas[..3], &cam, None, &cfg),
        Err(GeometryError::LengthMismatch(3, 40))
    );
    sigmas[0] = f64::NAN;
    assert_eq!(
        solve_pnp_ransac_with_sigmas(&world, &px, &sigmas, &cam, None, &cfg),
        Err(GeometryError::NonFinite)
    );
}
